"""The contention world as a Gymnasium environment: every request of a run is one ``step``.

    import gymnasium, yafs_safetail
    env = gymnasium.make("yafs_safetail/SafeTailContention-v0", use_case=1, users=50, load=0.5,
                         n_requests=2000)
    observation, info = env.reset(seed=17)
    observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

It is the run :func:`~yafs_safetail.contention.run.run_policy` makes, the load sweep's world:
``reset(seed=s)`` builds the :class:`~yafs_safetail.contention.world.ContentionWorld` of
``ContentionConfig(seed=s, ...)`` with this environment's settings (every ``ContentionConfig``
field but the seed is a keyword here, with the same default) and runs ``run_policy`` on it with
a policy whose choices are the agent's actions. The agent dispatches **every** request, as the
sweep's SafeTail does, so each request is a step, in emission order, whichever user sent it;
ω^t is the one :class:`~yafs_safetail.contention.run.PolicyDispatcher` builds for any policy.
A fixed policy driven through the environment gives exactly ``run_policy``'s latencies (tested).

How the control is turned around without touching the engine: ``run_policy`` runs in a worker
thread, and the policy's ``choose`` hands ω^t to the caller and blocks until ``step`` hands back
the action (two one-slot queues). Exactly one of the two threads runs at any time, so the run is
the same sequence of operations as ``run_policy`` in one thread: deterministic. ``reset(seed=...)``
and ``close()`` end a run still under way (its thread leaves at once; none is left behind), and
an exception raised inside the run is raised again by the ``step`` or ``reset`` that met it,
with its own type and message. A generator (a coroutine) would need the engine to yield, which
it cannot without being edited.

Spaces and signals:

- **action**: ``Discrete(2^n - 1)``, a non-empty subset of the n servers in SafeTail's order
  (``methods.safetail.spaces.subset_of``), as ``SafeTail-v0``. The copies are sent all at once
  (``dispatch="all"``) or as a tied request (``dispatch="tied"``: cancelled once one starts
  running), SafeTail's two modes; hedged dispatch is not offered (it needs an order and a delay,
  which a subset does not give).
- **observation**: ω^t of the request to dispatch, field by field (``observation="dict"``, the
  fields of ``SafeTail-v0``; ``server_active_users`` is ℓ_i of the contention world: our running
  and waiting copies plus the background tenants; ``server_max_load`` each server's slots), or
  SafeTail's scaled state vector (``observation="vector"``, ``encode_state``).
- **reward**: a request's outcome comes later than its decision, after other requests have
  been dispatched. Step j's reward is the sum of the rewards of the requests that *completed*
  while the run went from request j's dispatch to request j + 1's (any requests, often earlier
  ones); ``info["completed"]`` holds their :class:`~yafs_safetail.record.RequestRecord` rows,
  each with its own ``reward``. Summed over a run, the rewards are every request's reward once.
  The per-request reward is ``reward=``: ``"paper"`` (Eq. 5, the preset's δ, against the τ of
  ``target=``, as the sweep's ``SafeTail``), ``"no-free-miss"`` (its contention variant) or
  ``"latency-cost"`` (``SafeTail-CA``'s: −log(L_R/τ) less the price of the copies at the load
  the agent observed).
- **episode**: ``episode_requests`` steps (default: the whole run, ``n_requests``); the last
  returns ``truncated=True`` (``terminated`` is always False). ``reset()`` without a seed goes on
  with the same run (its servers still busy, its requests in flight reported at the next step);
  a run used up is followed by a fresh world seeded from the environment's generator. The
  step that dispatches a run's last request also runs the world until every copy has settled:
  its ``info["completed"]`` holds every outstanding request, and ``info["run"]`` the
  :class:`~yafs_safetail.contention.run.PolicyRun` (``summarise(info["run"])`` is the sweep's
  row for the agent).

``info`` also carries ``observation`` (the :class:`~yafs_safetail.edge.observation.Observation`
of the request to dispatch, for policies written against it) and ``request`` (its index). After
a run's last request there is none to dispatch: that step repeats the last one's observation.
"""

from __future__ import annotations

import dataclasses
import inspect
import queue
import threading
import weakref
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from yafs_safetail.contention.run import TARGETS, PolicyRun, run_policy
from yafs_safetail.contention.world import (
    ContentionConfig,
    ContentionError,
    ContentionWorld,
    check_contention_config,
)
from yafs_safetail.edge.inputs import TraceInputs
from yafs_safetail.edge.observation import Observation
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.methods.policy import Policy
from yafs_safetail.methods.safetail.policy import SAFETAIL_DISPATCH
from yafs_safetail.methods.safetail.presets import PRESET_NAMES, get_preset
from yafs_safetail.methods.safetail.reward import REWARD_NAMES, REWARDS, copy_price, latency_score
from yafs_safetail.methods.safetail.spaces import (
    StateScales,
    n_actions,
    subset_of,
)
from yafs_safetail.observation_space import OBSERVATION_KINDS, encode_observation, observation_space
from yafs_safetail.record import PHASES, RequestRecord
from yafs_safetail.settings.declare import config_from_keywords, keyword_names

#: The name of the threads that run a world (tests count them to find leaks).
ENGINE_THREAD_NAME = "contention-env-engine"
_DEFAULTS = ContentionConfig()
#: The world's settings the environment takes as keywords: every ContentionConfig field but the
#: seed, which ``reset`` gives (a field declared there is a keyword here with nothing else edited).
ENV_SETTINGS: tuple[str, ...] = tuple(name for name in keyword_names(ContentionConfig) if name != "seed")


class _StopRun(BaseException):
    """Raised inside the engine thread to end a run the environment no longer needs.

    A BaseException, so that no ``except Exception`` on the way up can swallow it.
    """


class _Stop:
    """What the caller sends instead of an action to end the run."""


class _AgentsChoices(Policy):
    """The engine thread's side of the handoff: ω^t out, the agent's subset back in.

    ``choose`` runs in the engine thread: it puts ω^t on ``to_agent`` and blocks on
    ``to_engine`` for the subset (or :class:`_Stop`). ``feedback`` keeps every record; the
    caller takes them while the engine thread is blocked, so the list is never used by both.
    """

    def __init__(self, n_servers: int, dispatch: str, name: str) -> None:
        super().__init__(n_servers, np.random.default_rng(0))  # never drawn from
        self.dispatch = dispatch
        self.name = name
        self.to_agent: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=1)
        self.to_engine: queue.Queue[tuple[int, ...] | _Stop] = queue.Queue(maxsize=1)
        self.completed: list[RequestRecord] = []

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        self.to_agent.put(("choose", observation))
        answer = self.to_engine.get()
        if isinstance(answer, _Stop):
            raise _StopRun
        return answer

    def feedback(self, outcome: RequestRecord) -> None:
        self.completed.append(outcome)


class _EngineRun:
    """One world's ``run_policy`` in a thread of its own, driven one decision at a time."""

    def __init__(self, world: ContentionWorld, agent: _AgentsChoices, target: str) -> None:
        self.agent = agent
        self.thread = threading.Thread(target=self._main, args=(world, agent, target),
                                       name=ENGINE_THREAD_NAME, daemon=True)
        self.thread.start()

    @staticmethod
    def _main(world: ContentionWorld, agent: _AgentsChoices, target: str) -> None:
        try:
            run = run_policy(world, agent, target=target)
        except _StopRun:
            return
        except BaseException as exc:  # noqa: BLE001 - handed to the caller, which raises it
            agent.to_agent.put(("failed", exc))
            return
        agent.to_agent.put(("finished", run))

    def next_message(self) -> tuple[str, Any]:
        """Waits for the run's next request to dispatch, its end, or its failure."""
        return self.agent.to_agent.get()

    def stop(self) -> None:
        """Ends the run: a thread waiting for an action leaves at once; one that has ended is
        joined. Safe to call more than once."""
        if self.thread.is_alive():
            # Alive means blocked in choose (or about to post its end, which needs no answer).
            self.agent.to_engine.put(_Stop())
            self.thread.join()


class ContentionEnv(gymnasium.Env[Any, Any]):
    """The contention world's dispatch problem as a Gymnasium environment (module docstring).

    The world's settings are those of
    :class:`~yafs_safetail.contention.world.ContentionConfig` (its seed comes from
    ``reset``); the rest say how the agent's choices are sent, seen and rewarded.

    Args:
        dispatch: ``"all"`` (every copy at once) or ``"tied"``.
        target: the τ of the records and rewards: ``"eq4"`` or ``"observed-load"``.
        reward: ``"paper"`` (Eq. 5), ``"no-free-miss"`` or ``"latency-cost"``.
        preset: the learner preset whose δ the Eq. 5 rewards use.
        observation: ``"dict"`` or ``"vector"``.
        episode_requests: steps per episode (None: ``n_requests``, one run per episode).
        method_name: the ``method`` of the records in ``info["completed"]``.
        settings: the world's, any of :data:`ENV_SETTINGS` (every ``ContentionConfig`` field but
            the seed, with its default and check: ``use_case``, ``n_requests``, ``users``,
            ``load``, ``queue``, ``topology``, ``failures``, ``target_latency_s``...); paths may be
            given as text.

    Raises:
        ValueError: a bad argument (one line naming it).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        dispatch: str = "all",
        target: str = "eq4",
        reward: str = "paper",
        preset: str = "paper",
        observation: str = "dict",
        episode_requests: int | None = None,
        method_name: str = "agent",
        **settings: Any,
    ) -> None:
        for name, value, valid in (("dispatch", dispatch, SAFETAIL_DISPATCH), ("target", target, TARGETS),
                                   ("reward", reward, REWARD_NAMES), ("preset", preset, PRESET_NAMES),
                                   ("observation", observation, OBSERVATION_KINDS)):
            if value not in valid:
                raise ContentionError(f"{name}: expected one of {', '.join(valid)}, got {value!r}")
        if episode_requests is not None and (isinstance(episode_requests, bool)
                                             or not isinstance(episode_requests, int) or episode_requests < 1):
            raise ContentionError(f"episode_requests: expected a positive integer, got {episode_requests!r}")
        if settings.get("phase", _DEFAULTS.phase) not in PHASES:
            raise ContentionError(f"phase: expected one of {', '.join(PHASES)}, got {settings['phase']!r}")
        self.config: ContentionConfig = config_from_keywords(ContentionConfig, settings, ENV_SETTINGS,
                                                             "SafeTailContention-v0", seed=0)
        check_contention_config(self.config, style="field")
        arrivals_csv = self.config.arrivals_csv
        # The seed-0 world checks every setting and input file now, and its trace inputs and
        # scenario serve every later world (they do not depend on the seed).
        probe = ContentionWorld(dataclasses.replace(self.config, n_requests=1) if arrivals_csv is None
                                else self.config)
        self._inputs: TraceInputs = probe.inputs
        self._scenario: EdgeScenario = probe.scenario
        self.use_case = probe.use_case
        self.n_servers = n = probe.n_servers
        self.dispatch, self.target, self.reward_name = dispatch, target, reward
        self.delta = get_preset(preset, self.use_case.number).delta
        self.episode_requests = episode_requests
        self.method_name = method_name
        self.action_space = spaces.Discrete(n_actions(n))
        self._scales = StateScales.for_use_case(self.use_case.number)
        n_gamma, n_location = len(self.use_case.gamma_columns), len(self._scenario.user_location)
        self.observation_space = observation_space(observation, n, n_gamma, n_location)
        self.world: ContentionWorld | None = None
        self._run: _EngineRun | None = None
        self._stop_on_collect: weakref.finalize | None = None
        self._observation: Observation | None = None
        self._world_over = True
        self._episode_over = True
        self._episode_step = 0
        # The copy price of each request in flight (latency-cost reward), known at dispatch.
        self._price_by_request: dict[int, float] = {}

    # ----------------------------------------------------------------------------- the loop

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None or self._world_over:
            world_seed = seed if seed is not None else int(self.np_random.integers(2**31 - 1))
            self._start_world(world_seed)
        self._episode_over = False
        self._episode_step = 0
        assert self._observation is not None
        return self._encode(self._observation), self._info()

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        if self._episode_over or self._run is None or self._observation is None:
            raise RuntimeError("the episode is over: call reset() before step()")
        if not self.action_space.contains(action):
            raise ContentionError(f"action: expected an integer in 0..{n_actions(self.n_servers) - 1}, got {action!r}")
        subset = subset_of(int(action), self.n_servers)
        if self.reward_name == "latency-cost":
            active = self._observation.server_active_users
            self._price_by_request[self._observation.step] = float(copy_price(sum(int(active[i]) for i in subset)))
        self._run.agent.to_engine.put(subset)
        run = self._await_request()
        completed = [self._rewarded(record) for record in self._run.agent.completed]
        self._run.agent.completed.clear()
        self._episode_step += 1
        truncated = self._world_over or (self.episode_requests is not None
                                         and self._episode_step >= self.episode_requests)
        self._episode_over = truncated
        info = self._info()
        info["completed"] = tuple(completed)
        if run is not None:
            info["run"] = run
        assert self._observation is not None
        total = float(sum(record.reward for record in completed))
        return self._encode(self._observation), total, False, truncated, info

    def close(self) -> None:
        """Ends the run under way, if any (its thread with it)."""
        self._end_run()
        super().close()

    # ----------------------------------------------------------------------------- helpers

    def _start_world(self, seed: int) -> None:
        self._end_run()
        self.world = ContentionWorld(dataclasses.replace(self.config, seed=seed), self._inputs, self._scenario)
        agent = _AgentsChoices(self.n_servers, self.dispatch, self.method_name)
        self._run = _EngineRun(self.world, agent, self.target)
        # An environment dropped without close() still ends its run's thread.
        self._stop_on_collect = weakref.finalize(self, self._run.stop)
        self._world_over = False
        self._observation = None
        self._price_by_request.clear()
        if self._await_request() is not None:
            raise ContentionError("n_requests: the run ended before its first request")

    def _await_request(self) -> PolicyRun | None:
        """Lets the run go on to its next request (ω^t kept), or to its end (the run returned)."""
        assert self._run is not None
        kind, payload = self._run.next_message()
        if kind == "choose":
            self._observation = payload
            return None
        self._world_over = True
        self._end_run()
        if kind == "failed":
            self._episode_over = True
            raise payload
        run: PolicyRun = payload
        return run

    def _end_run(self) -> None:
        if self._stop_on_collect is not None:
            self._stop_on_collect()  # calls _EngineRun.stop once, then lets go of the run
            self._stop_on_collect = None

    def _rewarded(self, record: RequestRecord) -> RequestRecord:
        if self.reward_name == "latency-cost":
            value = latency_score(record.latency_s, record.target_s) - self._price_by_request.pop(record.step)
        else:
            value = REWARDS[self.reward_name](record.latency_s, record.target_s, len(record.servers),
                                              self.n_servers, self.delta)
        return dataclasses.replace(record, reward=value)

    def _info(self) -> dict[str, Any]:
        assert self._observation is not None
        return {"observation": self._observation, "request": self._observation.step}

    def _encode(self, observation: Observation) -> Any:
        return encode_observation(self.observation_space, observation, self._scales)


def _signature() -> inspect.Signature:
    """``ContentionEnv``'s signature with every world setting written out (``help()``,
    ``inspect``), each with its declared default."""
    own = [parameter for parameter in inspect.signature(ContentionEnv.__init__).parameters.values()
           if parameter.kind is not inspect.Parameter.VAR_KEYWORD]
    declared = [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=getattr(_DEFAULTS, name))
                for name in ENV_SETTINGS]
    return inspect.Signature([*own, *declared])


ContentionEnv.__init__.__signature__ = _signature()  # type: ignore[attr-defined]
