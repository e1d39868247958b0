"""SafeTail (§III) as a policy: the learned FNN picks each request's subset of edge servers.

It is a :class:`~yafs_safetail.methods.learning.LearningPolicy`: a run trains, checkpoints,
saves and resumes it as it does any user's learner.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from yafs_safetail.defaults import SAFETAIL_DISPATCH as SAFETAIL_DISPATCH
from yafs_safetail.edge.failures import END_REPLY
from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.learning import LearningPolicy
from yafs_safetail.methods.objectives import objectives_bringing
from yafs_safetail.methods.policy import PolicyError
from yafs_safetail.methods.safetail.persistence import POLICY_FILE
from yafs_safetail.methods.safetail.reward import (
    REWARD_NAMES,
    REWARDS,
    copy_price,
    priced_latency_score,
    priced_reward,
)
from yafs_safetail.methods.safetail.spaces import (
    StateScales,
    encode_state,
    membership_matrix,
    subset_of,
)
from yafs_safetail.record import RequestRecord

if TYPE_CHECKING:
    from yafs_safetail.methods.safetail.learner import SafeTailLearner

#: The fewest copies the value learner's greedy choice sends as a tied request (when n >= 2).
#: A lone copy has no sibling to take over when its queue is long, and under load the
#: price of a second copy grows with the queues, so without this floor the learner sent lone
#: copies exactly when queues were longest, and they made its p99 (docs/deviations.md D13).
TIED_MIN_COPIES = 2


class SafeTailPolicy(LearningPolicy):
    """ε-greedy choices of a :class:`~yafs_safetail.methods.safetail.learner.SafeTailLearner`.

    :meth:`choose` encodes ω^t, asks the learner for an action (Eq. 3: ε-greedy while
    ``training``, the argmax otherwise) and maps it to its subset; :meth:`feedback` puts the
    Eq. 5 reward of L_R against τ into the record and, while ``training``, hands the tuple
    (ω^t, A^{t+1}, R^{t+1}) to the learner (a training round every κ tuples). With the
    ``"latency-cost"`` reward the learner is given only the reward's latency score, and the
    price of each action's copies (the jobs on its servers at dispatch) is subtracted from the
    network's predictions when choosing; the learner's energy price and failure penalty (D15)
    are subtracted from the score it learns (:func:`~yafs_safetail.methods.safetail.reward.
    priced_latency_score`), from Eq. 5 with the §III learner.

    Args:
        n_servers: n; must match the learner's.
        rng: unused (the learner draws from its own generators, seeded with the run's seed);
            kept for the common policy signature.
        learner: the learner.
        scales: the state normalisation (``StateScales.for_use_case``).
        training: explore and learn (the training phase) or act greedily and frozen (testing).
        reward_name: the reward of :data:`~yafs_safetail.methods.safetail.reward.REWARDS`
            (``"paper"``, Eq. 5, everywhere but the contention world's variants;
            ``"latency-cost"`` needs a learner whose objective brings it, ``"value"``: its
            ``own_reward``).
        dispatch: how the contention world sends the chosen subset: ``"all"`` (every copy at
            once, the paper) or ``"tied"`` (the copies cancel each other once one starts
            running, as :class:`~yafs_safetail.methods.hedging.Tied`; contention world only).
            With the ``"latency-cost"`` reward and ``"tied"``, the greedy choice is among subsets
            of at least two servers (:data:`TIED_MIN_COPIES`); exploration still tries every
            subset.

    Attributes:
        decision_time_s: wall time spent encoding states and choosing actions.
        training_time_s: wall time spent in ``learner.observe`` (storing and training).
        loaded_from: the saved policy :meth:`load` read, or None (trained in this run).
    """

    def __init__(self, n_servers: int, rng: np.random.Generator, *, learner: SafeTailLearner,
                 scales: StateScales, training: bool, reward_name: str = "paper",
                 dispatch: str = "all") -> None:
        if learner.n_servers != n_servers:
            raise PolicyError(
                f"SafeTail: the policy is for {learner.n_servers} servers, the topology has {n_servers}"
            )
        self.name = "SafeTail"
        super().__init__(n_servers, rng)
        self.learner = learner
        self.scales = scales
        self.training = training
        if reward_name not in REWARD_NAMES:
            raise PolicyError(f"SafeTail: unknown reward {reward_name!r}; valid: {', '.join(REWARD_NAMES)}")
        if reward_name not in REWARDS and learner.objective.own_reward != reward_name:
            owners = " or ".join(objectives_bringing(reward_name))
            raise PolicyError(f"SafeTail: the {reward_name} reward needs a learner with the {owners} objective")
        self._reward = REWARDS.get(reward_name)  # None: the latency-cost reward
        if dispatch not in SAFETAIL_DISPATCH:
            raise PolicyError(f"SafeTail: unknown dispatch {dispatch!r}; valid: {', '.join(SAFETAIL_DISPATCH)}")
        self.dispatch = dispatch
        self._membership = membership_matrix(n_servers)
        # Added to each action's price when choosing greedily: +inf for a subset too small to be
        # sent as a tied request. None (nothing to add) for §III's learner, for "all", and with
        # one server, which has no sibling to send.
        self._too_few_copies: np.ndarray | None = None
        if dispatch == "tied" and self._reward is None and n_servers >= TIED_MIN_COPIES:
            self._too_few_copies = np.where(self._membership.sum(axis=1) < TIED_MIN_COPIES, np.inf, 0.0)
        self.decision_time_s = 0.0
        self.training_time_s = 0.0
        self.loaded_from: Path | None = None
        # Per request in flight: the state, the action, ε, and the price of its copies.
        self._decisions: dict[int, tuple[np.ndarray, int, float, float]] = {}

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None
        started = time.perf_counter()
        state = encode_state(observation, self.scales)
        epsilon = self.learner.epsilon if self.training else 0.0
        if self._reward is None:
            # The latency-cost reward: the network predicts each action's latency score, and the
            # price of its copies, known now, is subtracted exactly rather than learned.
            prices = copy_price(self._membership @ observation.server_active_users)
            floored = prices if self._too_few_copies is None else prices + self._too_few_copies
            action = self.learner.act(state, explore=self.training, action_cost=floored)
            price = float(prices[action])
        else:
            action = self.learner.act(state, explore=self.training)
            price = 0.0
        subset = subset_of(action, self.n_servers)
        self._decisions[observation.step] = (state, action, epsilon, price)
        self.decision_time_s += time.perf_counter() - started
        return subset

    def feedback(self, outcome: RequestRecord) -> RequestRecord:
        state, action, epsilon, price = self._decisions.pop(outcome.step)
        config = self.learner.config
        replied = outcome.end_reason == END_REPLY
        if self._reward is None:
            # reward_latency_cost: the network learns the request's score, with its energy and
            # failure prices (known only now that it ended); its copies' price was known at
            # dispatch and is subtracted there, not learned.
            learned = priced_latency_score(outcome.latency_s, outcome.target_s, outcome.energy_j, replied,
                                           config.energy_price_per_j, config.failure_penalty)
            value = learned - price
        else:
            eq5 = self._reward(outcome.latency_s, outcome.target_s, len(outcome.servers), self.n_servers,
                               config.delta)
            value = priced_reward(eq5, outcome.energy_j, replied, config.energy_price_per_j,
                                  config.failure_penalty)
            learned = value
        if self.training:
            started = time.perf_counter()
            self.learner.observe(state, action, learned)
            self.training_time_s += time.perf_counter() - started
        return dataclasses.replace(outcome, reward=value, epsilon=epsilon)

    # -- LearningPolicy: what a run asks of every learning method -------------------------

    def end_training(self) -> str:
        return (f"training rounds {self.learner.n_training_rounds}, "
                f"final ε {self.learner.epsilon:.4f}")

    def policy_file(self) -> str:
        return POLICY_FILE

    def save(self, path: Path) -> None:
        """The network as a reproducible ``.keras`` file and its JSON sidecar
        (``methods.safetail.persistence``)."""
        self.learner.save(path)

    def load(self, path: Path) -> None:
        """Evaluate a saved policy: the learner :meth:`save` wrote, for testing only.

        Raises:
            PolicyFileError: a missing or inconsistent file.
            PolicyError: a policy for another number of servers.
        """
        from yafs_safetail.methods.safetail.learner import SafeTailLearner

        learner = SafeTailLearner.load(path, training=False)
        if learner.n_servers != self.n_servers:
            raise PolicyError(f"SafeTail: {path} is for {learner.n_servers} servers, the topology "
                              f"has {self.n_servers}")
        own_reward = learner.objective.own_reward
        if (own_reward is not None) != (self._reward is None):
            # A value network predicts latency scores and §III's predicts action probabilities:
            # each is evaluated with the reward it was trained with (the value learner's own, or
            # Eq. 5), else its greedy choices would not be the ones it was trained to make.
            self._reward = None if own_reward is not None else REWARDS["paper"]
        self.learner = learner
        self.loaded_from = Path(path)

    def checkpoint_state(self) -> dict[str, Any]:
        """The learner's whole training state (``SafeTailLearner.training_state``)."""
        return self.learner.training_state()

    def restore_checkpoint_state(self, state: object) -> None:
        if not isinstance(state, dict):
            raise PolicyError(f"SafeTail: a checkpoint state is a dict, got {type(state).__name__}")
        self.learner.restore_training_state(state)

    def run_json_fields(self) -> dict[str, Any]:
        """The run's preset and β (the learner's settings: a saved policy's own), the learner's
        settings, what training did, and where the policy comes from."""
        config = self.learner.config
        return {
            "preset": config.name,
            "beta": config.beta,
            "learner": config.to_dict(),
            "training_rounds": self.learner.n_training_rounds,
            "final_epsilon": self.learner.epsilon,
            "policy_source": str(self.loaded_from) if self.loaded_from else POLICY_FILE,
        }
