"""The Gymnasium environment: the experiment's simulation, one request per ``step``.

    import gymnasium, yafs_safetail
    env = gymnasium.make("yafs_safetail/SafeTail-v0", use_case=1)
    observation, info = env.reset(seed=0)
    observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

It is the same simulation ``run_usecase.py`` runs (``sim.runner.deploy``: the YAFS core, the edge
model's delay hooks, the policy selection), driven from outside: ``reset(seed=s)`` draws the
world ``run_usecase.py --seed s`` trains in (or tests in, ``phase="test"``), and each ``step``
sends one request to the chosen subset and runs the simulation until that request has its
first reply. SafeTail trained through this environment gives the same records and weights as
``run_usecase.py`` (tested). Its world comes from the same recipe as the experiment's
(``worlds.recipe``), so it takes the same world settings, as keywords named as the
run's fields (:data:`ENV_SETTINGS`, derived from ``settings.experiment``'s declarations: a world
setting declared there is a keyword here with nothing else edited): ``target_latency_s``,
``load_peak_users`` and ``target_compute`` as ``--target-latency-s``, ``--load-peak-users`` and
``--target-compute``, the failures and power models (``failure_mttf_s``, ``failure_mttr_s``,
``failure_probability``, ``down_intervals``, ``timeout_s``, ``server_idle_w``, ``server_max_w``;
docs/failures_energy.md) and the reward's prices.

Spaces:

- **action**: ``Discrete(2^n - 1)``, the index of a non-empty subset of the n servers, in the
  order SafeTail's network outputs them (``methods.safetail.spaces.subset_of``). Every action
  is a valid subset, so no rule for an empty choice is needed, and agents see exactly the
  choices SafeTail's softmax ranks; n <= 10 keeps it at most 1,023 actions.
- **observation** (``observation="dict"``, the default): ω^t of Definition 1, one entry per
  :class:`~yafs_safetail.edge.observation.Observation` field, float32, per-server arrays of
  shape (n,) and scalars of shape (1,): ``server_uplink_bps``, ``server_downlink_bps``,
  ``server_memory_util``, ``server_cpu_util``, ``server_active_users``,
  ``server_median_propagation_s``, ``server_max_load``, ``input_bytes``, ``est_output_bytes``,
  ``gamma`` (absent when the use case has no Γ, UC1), ``user_location``, ``user_uplink_bps``,
  ``user_downlink_bps``. ``observation="vector"`` gives SafeTail's scaled state vector
  (``encode_state``) instead, ready for an MLP.
- **reward**: Eq. 5 with the preset's δ (always <= 0), less ``energy_price_per_j`` × the
  request's energy and ``failure_penalty`` when it ended without a reply (both 0 by default:
  Eq. 5 exactly; docs/deviations.md D15).
- **episode**: α_s requests (the world's background load is drawn per episode of α_s steps);
  the last step of an episode returns ``truncated=True`` (a time limit: the task itself never
  terminates, so ``terminated`` is always False). ``reset()`` without a seed continues with
  the world's next request; a world used up (its ``n_steps`` requests) is followed by a fresh
  one seeded from the environment's generator.

``info`` carries ``observation`` (the :class:`Observation`, for policies written against it)
and, after a step, ``record``: the request's :class:`~yafs_safetail.record.RequestRecord`
(latency, target, refusals, the winning copy's Eq. 1 parts, the reward), ``end_reason`` (why
the request ended: ``"reply"``, ``"all_refused"``, ``"all_lost"``, ``"timeout"``) and ``energy_j``
(what its copies cost). The observation says nothing of failures: an agent learns of them only
through these, as SafeTail does through its records.
"""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from yafs_safetail.edge.failures import END_REPLY
from yafs_safetail.edge.observation import Observation
from yafs_safetail.edge.scenario import default_placement
from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.methods.policy import Policy
from yafs_safetail.methods.safetail.reward import priced_reward, reward
from yafs_safetail.methods.safetail.spaces import StateScales, n_actions, subset_of
from yafs_safetail.observation_space import OBSERVATION_KINDS, encode_observation, observation_space
from yafs_safetail.record import PHASES, RequestRecord
from yafs_safetail.settings.declare import config_from_keywords, field_of, keyword_names
from yafs_safetail.settings.experiment import ExperimentConfig, WorldSetup
from yafs_safetail.sim.runner import Simulation, SimulationError, deploy
from yafs_safetail.worlds.recipe import world_recipe

#: The run's settings the environment takes as keywords (named and checked as the run's fields):
#: the use case, preset and budget, every setting of the world (``WorldSetup``) and the D15
#: prices of the reward. The world's settings object (``world``) is one of them: None, the
#: preset's world, as a run's.
ENV_SETTINGS: tuple[str, ...] = ("use_case", "preset", "steps_scale", *keyword_names(WorldSetup),
                                 "energy_price_per_j", "failure_penalty")


class _AgentsChoice(Policy):
    """The environment's side of the policy selection: the subset the agent gave to ``step``."""

    observes = False  # the environment builds ω^t itself, before the request is issued

    def __init__(self, n_servers: int, rng: np.random.Generator) -> None:
        super().__init__(n_servers, rng)
        self.subset: tuple[int, ...] | None = None
        self.record: RequestRecord | None = None

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        subset, self.subset = self.subset, None
        if subset is None:
            raise SimulationError("a request was issued before the agent chose its subset")
        return subset

    def feedback(self, outcome: RequestRecord) -> None:
        self.record = outcome


class SafeTailEnv(gymnasium.Env[Any, Any]):
    """SafeTail's decision problem as a Gymnasium environment (see the module docstring).

    Args:
        phase: ``"train"`` (the preset's training budget and world) or ``"test"``.
        observation: ``"dict"`` (ω^t field by field) or ``"vector"`` (SafeTail's scaled state).
        results_path: YAFS result CSVs prefix (None: none written).
        method_name: the ``method`` of the records in ``info["record"]``.
        settings: any of :data:`ENV_SETTINGS`, as the run's field of that name (its default,
            check and meaning: ``settings.experiment``, or ``run_usecase.py --help``), e.g.
            ``use_case`` (1, 2, 3), ``preset``, ``steps_scale``, ``topology``, ``placement``
            (default: the topology's file name under placements/), ``target_latency_s``,
            ``failure_probability``, ``energy_price_per_j``; paths may be given as text.

    Raises:
        ValueError: a bad argument or input file (one line naming it).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        phase: str = "train",
        observation: str = "dict",
        results_path: str | Path | None = None,
        method_name: str = "agent",
        **settings: Any,
    ) -> None:
        if phase not in PHASES:
            raise ValueError(f"phase: expected one of {PHASES}, got {phase!r}")
        if observation not in OBSERVATION_KINDS:
            raise ValueError(f"observation: expected one of {OBSERVATION_KINDS}, got {observation!r}")
        config: ExperimentConfig = config_from_keywords(ExperimentConfig, settings, ENV_SETTINGS, "SafeTail-v0")
        if "placement" not in settings:  # the topology's own, as the run command's default
            config = dataclasses.replace(config, placement=default_placement(config.topology))
        # The experiment's own recipe: the same checks, world settings and overrides.
        self._recipe = world_recipe(config, style="field")
        self.use_case = self._recipe.use_case
        self.learner_config = self._recipe.learner
        self.phase = phase
        self.n_steps = self._recipe.n_steps(phase)
        self.episode_steps = self.learner_config.episode_steps
        self.delta = self.learner_config.delta
        self.step_interval_s = float(config.step_interval_s)
        self.results_path = None if results_path is None else Path(results_path)
        if self.results_path is not None:
            self.results_path.parent.mkdir(parents=True, exist_ok=True)
        self.scenario = self._recipe.scenario
        self.n_servers = n = self.scenario.n_servers
        self.action_space = spaces.Discrete(n_actions(n))
        self._scales = StateScales.for_use_case(self.use_case.number)
        n_gamma, n_location = len(self.use_case.gamma_columns), len(self.scenario.user_location)
        self.observation_space = observation_space(observation, n, n_gamma, n_location)
        self.world: EdgeWorld | None = None
        self._simulation: Simulation | None = None
        self._agent = _AgentsChoice(n, np.random.default_rng(0))
        self._agent.name = method_name
        self._step = 0
        self._observation: Observation | None = None
        self._episode_over = True

    # ----------------------------------------------------------------------------- the loop

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None or self.world is None or self._step >= self.world.n_steps:
            world_seed = seed if seed is not None else int(self.np_random.integers(2**31 - 1))
            self._start_world(world_seed)
        self._episode_over = False
        assert self.world is not None
        self._observation = self._observe()
        return self._encode(self._observation), {"observation": self._observation}

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        if self._episode_over or self._simulation is None or self.world is None:
            raise RuntimeError("the episode is over: call reset() before step()")
        if not self.action_space.contains(action):
            raise ValueError(f"action: expected an integer in 0..{n_actions(self.n_servers) - 1}, got {action!r}")
        subset = subset_of(int(action), self.n_servers)
        self._agent.subset, self._agent.record = subset, None
        self._simulation.run_until_request(self._step + 1)
        record = self._agent.record
        if record is None:
            raise SimulationError(
                f"request {self._step} did not complete within step_interval_s={self.step_interval_s}"
            )
        prices = self.learner_config
        value = priced_reward(reward(record.latency_s, record.target_s, len(subset), self.n_servers, self.delta),
                              record.energy_j, record.end_reason == END_REPLY,
                              prices.energy_price_per_j, prices.failure_penalty)
        record = dataclasses.replace(record, reward=value)
        self._step += 1
        truncated = self._step % self.episode_steps == 0 or self._step >= self.world.n_steps
        self._episode_over = truncated
        if self._step < self.world.n_steps:
            self._observation = self._observe()
        assert self._observation is not None
        info = {"observation": self._observation, "record": record,
                "end_reason": record.end_reason, "energy_j": record.energy_j}
        return self._encode(self._observation), value, False, truncated, info

    # ----------------------------------------------------------------------------- helpers

    def _start_world(self, seed: int) -> None:
        self.world = self._recipe.make_world(self.phase, seed)
        self._simulation = deploy(self.world, self._agent, self.step_interval_s, self.results_path)
        self._step = 0

    def _observe(self) -> Observation:
        """ω^t of the next request, read when the simulation has run up to its issue time."""
        assert self._simulation is not None
        self._simulation.run_until_request(self._step)
        return self._simulation.edge.observe(self._step)

    def _encode(self, observation: Observation) -> Any:
        return encode_observation(self.observation_space, observation, self._scales)


def _signature() -> inspect.Signature:
    """``SafeTailEnv``'s signature with every setting it takes written out (``help()``,
    ``inspect``, IDEs), each with its declared default."""
    own = [parameter for parameter in inspect.signature(SafeTailEnv.__init__).parameters.values()
           if parameter.kind is not inspect.Parameter.VAR_KEYWORD]
    declared = [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY,
                                  default=field_of(ExperimentConfig, name).default) for name in ENV_SETTINGS]
    return inspect.Signature([*own, *declared])


SafeTailEnv.__init__.__signature__ = _signature()  # type: ignore[attr-defined]
