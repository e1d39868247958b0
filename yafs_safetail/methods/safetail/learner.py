"""The SafeTail learner: ε-greedy decisions (Eq. 3) and the training loop: each (ω, A, R) tuple
stored with its objective's target, a training round every κ tuples.

What a reward becomes as a training target is the objective's (``LearnerConfig.objective``;
``methods.objectives``: §III's target vector, the original code's Q-style targets,
each action's value). ``target_vector`` stays importable from here."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from yafs_safetail.methods.objectives import Objective, Replay
from yafs_safetail.methods.objectives import target_vector as target_vector
from yafs_safetail.methods.safetail.network import (
    build_network,
    enable_determinism,
    fast_forward,
    make_round_updates,
)
from yafs_safetail.methods.safetail.presets import LearnerConfig
from yafs_safetail.methods.safetail.spaces import n_actions


class SafeTailLearner:
    """The FNN policy, its ε-greedy exploration, and its training rounds.

    Typical use from a selection::

        state = encode_state(obs, scales)
        action = learner.act(state, explore=True)      # then dispatch to subset_of(action, n)
        ...                                            # when the request completes:
        r = reward(latency_s, target_s, len(subset), n, learner.config.delta)
        learner.observe(state, action, r)              # trains every κ tuples

    Randomness: one ``SeedSequence(seed)`` gives the exploration generator, the minibatch
    shuffling generator and the initial-weight seeds; nothing is drawn from global state.

    Attributes:
        n_servers: n.
        n_actions: 2^n - 1.
        state_dim: Length of the encoded state.
        config: The preset.
        metadata: Free-form JSON-serialisable data saved with the policy (e.g. the state
            scales); empty unless given.
    """

    def __init__(
        self,
        n_servers: int,
        state_dim: int,
        config: LearnerConfig,
        seed: int,
        *,
        training: bool = True,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        """Build a fresh network.

        Args:
            n_servers: n, 1..10.
            state_dim: Length of the encoded state (``state_dim(n, g, d)``).
            config: A preset (see :func:`yafs_safetail.methods.safetail.presets.get_preset`).
            seed: The run's seed; also seeds Keras/TensorFlow process-wide (see
                :func:`yafs_safetail.methods.safetail.network.enable_determinism`).
            training: False for an evaluation-only learner.
            metadata: Saved alongside the weights.

        Raises:
            ValueError: bad ``n_servers``, ``state_dim`` or ``seed``.
        """
        self.n_actions = n_actions(n_servers)
        if isinstance(state_dim, bool) or not isinstance(state_dim, int) or state_dim < 1:
            raise ValueError(f"state_dim must be an integer >= 1, got {state_dim!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        self.n_servers = int(n_servers)
        self.state_dim = state_dim
        self.config = config
        # Resolved once: observe asks it on every stored tuple.
        self._objective = config.learning_objective
        self.metadata: dict[str, Any] = dict(metadata or {})
        self._training = bool(training)
        self._seed = seed
        explore_seq, shuffle_seq, init_seq = np.random.SeedSequence(seed).spawn(3)
        self._explore_rng = np.random.default_rng(explore_seq)
        self._shuffle_rng = np.random.default_rng(shuffle_seq)
        enable_determinism(seed)
        self._model = build_network(
            state_dim, self.n_actions, config, int(init_seq.generate_state(1)[0])
        )
        self._forward = fast_forward(self._model, self.config)
        capacity = config.replay_capacity
        self._states = np.zeros((capacity, state_dim), dtype=np.float32)
        # One target column per network output: n_networks copies of the action columns.
        self._targets = np.zeros((capacity, config.n_networks * self.n_actions), dtype=np.float32)
        # Only for an objective that keeps them (q-target): each tuple's next state, once the
        # next request has come (a tuple without one is left out of the rounds until it has).
        q_rows = capacity if self.objective.keeps_next_state else 0
        self._next_states = np.zeros((q_rows, state_dim), dtype=np.float32)
        self._has_next = np.zeros(q_rows, dtype=bool)
        self._n_stored = 0
        self._n_buffered = 0
        self._n_rounds = 0
        self._round_updates: Any = None
        self.last_round_loss: float | None = None

    # -- state -------------------------------------------------------------------------------

    @property
    def training(self) -> bool:
        """False in evaluation-only mode: ``act`` always exploits, ``observe`` stores nothing."""
        return self._training

    @training.setter
    def training(self, value: bool) -> None:
        self._training = bool(value)

    @property
    def epsilon(self) -> float:
        """Current ε: ε_start - decays·ε_decay, floored at ε_min, where decays counts training
        rounds, or stored tuples with ``config.epsilon_per_step``."""
        c = self.config
        decays = self._n_stored if c.epsilon_per_step else self._n_rounds
        return max(c.epsilon_min, c.epsilon_start - decays * c.epsilon_decay)

    @property
    def objective(self) -> Objective:
        """What the network is trained toward (``config.objective``'s objective)."""
        return self._objective

    @property
    def n_training_rounds(self) -> int:
        """Training rounds run so far."""
        return self._n_rounds

    @property
    def n_stored(self) -> int:
        """(state, action, reward) tuples observed in training mode so far."""
        return self._n_stored

    @property
    def model(self) -> Any:
        """The Keras model (read it; train only through :meth:`observe`)."""
        return self._model

    # -- decisions and learning --------------------------------------------------------------

    def act(self, state: np.ndarray, explore: bool, action_cost: np.ndarray | None = None) -> int:
        """Choose an action for one encoded state (Eq. 3).

        With ``explore`` in training mode: a uniformly random action with probability ε,
        otherwise the argmax of the network. Without ``explore``, or in evaluation mode:
        always the argmax (ε is not used and no random number is drawn).

        Args:
            state: float32 vector of length ``state_dim`` (from ``encode_state``).
            explore: Whether ε-greedy exploration applies (training phase).
            action_cost: Subtracted from the network's outputs before the argmax, one entry
                per action: a known part of the ``"value"`` objective's reward that the
                network need not learn (the copy price, D13). None: the outputs alone.

        Returns:
            The action index, 0..2^n - 2.
        """
        if explore and self._training and self._explore_rng.random() < self.epsilon:
            return int(self._explore_rng.integers(self.n_actions))
        if action_cost is None:
            return self._forward.best_action(state)
        return int((self._forward.logits(state) - action_cost).argmax())

    def observe(self, state: np.ndarray, action: int, reward: float) -> bool:
        """Store one (ω, A, R) tuple; run a training round every κ stored tuples.

        In evaluation mode nothing is stored and nothing trains.

        Args:
            state: The encoded state the action was chosen for.
            action: The action taken.
            reward: Its reward: Eq. 5's (<= 0) for the ``"target-vector"`` and ``"q-target"``
                objectives; any finite value for the ``"value"`` objective, whose network
                learns to predict it.

        Returns:
            True if this call ran a training round.

        Raises:
            ValueError: wrong state shape, action out of range, a positive reward (§III) or a
                non-finite one.
        """
        if not self._training:
            return False
        if state.shape != (self.state_dim,):
            raise ValueError(f"state must have shape ({self.state_dim},), got {state.shape}")
        slot = self._n_buffered % self.config.replay_capacity
        self.objective.write_target(self._targets[slot], action, reward, self.n_servers)
        if self.objective.keeps_next_state:
            # This state is the previous tuple's next state.
            if self._n_buffered:
                previous = (self._n_buffered - 1) % self.config.replay_capacity
                self._next_states[previous] = state
                self._has_next[previous] = True
            self._has_next[slot] = False
        self._states[slot] = state
        self._n_buffered += 1
        self._n_stored += 1
        if self._n_stored % self.config.kappa:
            return False
        self._train_round()
        return True

    def _train_round(self) -> None:
        c = self.config
        n_rows = min(c.replay_capacity, self._n_buffered)
        replay = self._replay(n_rows)
        states = replay.states
        targets = self.objective.round_targets(replay, self.predict_probabilities)
        # The rows a round may draw (q-target waits for a tuple's next state).
        candidates = self.objective.round_rows(replay)
        if c.replay_sampling == "uniform":
            batches = np.stack([
                self._shuffle_rng.choice(candidates, size=c.batch_size, replace=False)
                for _ in range(c.updates_per_round)
            ])
            if self._round_updates is None:
                self._round_updates = make_round_updates(self._model, self.objective)
            self.last_round_loss = self._round_updates(states, targets, batches)
        else:
            losses = []
            for _ in range(c.epochs_per_round):
                order = self._shuffle_rng.permutation(candidates)
                for start in range(0, n_rows, c.batch_size):
                    batch = order[start:start + c.batch_size]
                    losses.append(float(self._model.train_on_batch(states[batch], targets[batch])))
            self.last_round_loss = float(np.mean(losses))
        self._forward = fast_forward(self._model, self.config)
        self._n_rounds += 1

    def _replay(self, n_rows: int) -> Replay:
        """The first ``n_rows`` slots of the replay buffer (the ring buffer holds exactly the most
        recent n_rows tuples in slots 0..n_rows-1)."""
        if not self.objective.keeps_next_state:
            return Replay(self._states[:n_rows], self._targets[:n_rows])
        return Replay(self._states[:n_rows], self._targets[:n_rows], self._next_states[:n_rows],
                      self._has_next[:n_rows])

    def predict_probabilities(self, states: np.ndarray) -> np.ndarray:
        """The Keras model's outputs for a batch of states (for analysis, not speed): softmax
        probabilities (§III), or predicted values, K·(2^n - 1) columns with K value networks."""
        return np.asarray(self._model(np.asarray(states, dtype=np.float32), training=False))

    # -- training checkpoints (runs.checkpoint) ----------------------------------------------

    def training_state(self) -> dict[str, Any]:
        """Everything training changes, as plain values and NumPy arrays: the network's
        weights, Adam's slots and step count, the replay buffer, the counters and both random
        generators. :meth:`restore_training_state` on a learner built with the same arguments
        continues exactly where this one stands (same decisions, same updates)."""
        state: dict[str, Any] = {
            "weights": [np.array(w) for w in self._model.get_weights()],
            "optimizer": [np.array(v.numpy()) for v in self._model.optimizer.variables],
            "states": self._states.copy(),
            "targets": self._targets.copy(),
            "n_stored": self._n_stored,
            "n_buffered": self._n_buffered,
            "n_rounds": self._n_rounds,
            "last_round_loss": self.last_round_loss,
            "explore_rng": self._explore_rng.bit_generator.state,
            "shuffle_rng": self._shuffle_rng.bit_generator.state,
        }
        if self.objective.keeps_next_state:
            state["next_states"] = self._next_states.copy()
            state["has_next"] = self._has_next.copy()
        return state

    def restore_training_state(self, state: Mapping[str, Any]) -> None:
        """Continue from :meth:`training_state` of a learner built with the same arguments.

        Raises:
            ValueError: the state is of another network or buffer shape.
        """
        weights = list(state["weights"])
        variables = self._model.optimizer.variables
        if (len(weights) != len(self._model.get_weights()) or len(state["optimizer"]) != len(variables)
                or state["states"].shape != self._states.shape
                or state["targets"].shape != self._targets.shape
                or ("next_states" in state) != self.objective.keeps_next_state):
            raise ValueError("the checkpoint is of another network or replay buffer")
        self._model.set_weights(weights)
        for variable, value in zip(variables, state["optimizer"], strict=True):
            variable.assign(value)
        self._states[...] = state["states"]
        self._targets[...] = state["targets"]
        if "next_states" in state:
            self._next_states[...] = state["next_states"]
            self._has_next[...] = state["has_next"]
        self._n_stored = int(state["n_stored"])
        self._n_buffered = int(state["n_buffered"])
        self._n_rounds = int(state["n_rounds"])
        self.last_round_loss = state["last_round_loss"]
        self._explore_rng.bit_generator.state = state["explore_rng"]
        self._shuffle_rng.bit_generator.state = state["shuffle_rng"]
        self._forward = fast_forward(self._model, self.config)

    # -- persistence (methods.safetail.persistence) ----------------------------------------

    def save(self, path: str | Path) -> Path:
        """Write the network to ``path`` (``.keras``) and a JSON sidecar next to it; see
        :func:`~yafs_safetail.methods.safetail.persistence.save_learner`."""
        from yafs_safetail.methods.safetail.persistence import save_learner

        return save_learner(self, path)

    @classmethod
    def load(cls, path: str | Path, *, training: bool = False) -> SafeTailLearner:
        """Load a policy written by :meth:`save`; see
        :func:`~yafs_safetail.methods.safetail.persistence.load_learner`."""
        from yafs_safetail.methods.safetail.persistence import load_learner

        return load_learner(path, training=training)

