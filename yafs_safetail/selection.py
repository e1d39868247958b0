"""YAFS selections that send each request to a subset of the edge servers.

:class:`SubsetSelection` does the YAFS plumbing shared by every method: it maps the
request to its step, builds ω^t, asks the subclass for a subset of server indices
(:meth:`SubsetSelection.choose_subset`), returns one user -> AP -> server path per chosen
server (redundant dispatch: one copy each), routes every reply back to the user's sink,
and, once every copy has settled, builds a :class:`RequestRecord` (L_R = the first reply,
Eq. 2, or the on-device fallback when every copy was refused).

SafeTail itself (:class:`SafeTailSelection`, §III) and the paper's baselines (§V-B) are
subclasses: :class:`Oracle`, :class:`RandX`, :class:`MinLoadX`, :class:`MinPropX`.
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from yafs_safetail.edge.model import SINK_MODULE, EdgeModel
from yafs_safetail.edge.observation import Observation
from yafs_safetail.policy import StateScales, encode_state, reward, subset_of
from yafs_safetail.yafs.selection import Selection

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim
    from yafs_safetail.yafs.outcomes import RequestOutcome


class SelectionError(ValueError):
    """A bad selection parameter (e.g. x outside 1..n, an unknown method name)."""


@dataclass(frozen=True, slots=True)
class RequestRecord:
    """What one request achieved under one method.

    Attributes:
        method: the method's name (e.g. ``"Rand-2"``).
        step: the world step of the request.
        request_id: the core's request id.
        time_emit_s: when the user emitted it.
        latency_s: L_R (Eq. 2): the first reply's latency, or the fallback latency.
        target_s: τ (Eq. 4).
        servers: the chosen server indices, ascending.
        n_servers: n, the number of edge servers reachable.
        refused: copies refused (server at its load limit).
        fallback: True when every copy was refused and the on-device version answered.
        winner: server index of the first reply, -1 for a fallback.
        upload_s: Eq. 1 uploading terms (input + output) of the winning copy (NaN if fallback).
        propagation_s: Eq. 1 propagation terms of the winning copy (NaN if fallback).
        download_s: Eq. 1 downloading terms of the winning copy (NaN if fallback).
        compute_s: Eq. 1 compute term of the winning copy (NaN if fallback).
        reward: the Eq. 5 reward (SafeTail; NaN for methods that do not learn).
        epsilon: SafeTail's exploration rate when it decided (NaN for other methods).
    """

    method: str
    step: int
    request_id: Any
    time_emit_s: float
    latency_s: float
    target_s: float
    servers: tuple[int, ...]
    n_servers: int
    refused: int
    fallback: bool
    winner: int
    upload_s: float
    propagation_s: float
    download_s: float
    compute_s: float
    reward: float = math.nan
    epsilon: float = math.nan

    @property
    def n_selected(self) -> int:
        return len(self.servers)

    @property
    def access_rate(self) -> float:
        """|E_k| / n."""
        return len(self.servers) / self.n_servers

    @property
    def deviation_s(self) -> float:
        """Latency deviation τ - L_R."""
        return self.target_s - self.latency_s


class SubsetSelection(Selection):
    """Base class of every method that dispatches a request to a subset of edge servers.

    Subclasses implement :meth:`choose_subset`; they may override :meth:`request_completed`
    to learn from each completed request.

    Args:
        edge_model: the run's edge model (the Sim's link-delay and service hooks).
        on_record: called with every :class:`RequestRecord`; when None, records are
            appended to :attr:`records`.
        name: the method's name in records (default: :meth:`default_name`).

    Attributes:
        records: the collected records (when no ``on_record`` is given).
    """

    def __init__(
        self,
        edge_model: EdgeModel,
        on_record: Callable[[RequestRecord], None] | None = None,
        name: str | None = None,
    ) -> None:
        super().__init__()
        self.edge_model = edge_model
        self.name = name or self.default_name()
        self.records: list[RequestRecord] = []
        self._on_record = on_record if on_record is not None else self.records.append
        self._pending: dict[Any, tuple[int, tuple[int, ...], Observation | None]] = {}
        self._service_des: list[Any] | None = None
        self._sink_des: Any = None
        # Routes are fixed per subset (requests) and per server node (replies): build each once.
        self._request_routes: dict[tuple[int, ...], tuple[tuple[int, ...], tuple[list[list[Any]], list[Any]]]] = {}
        self._reply_routes: dict[Any, tuple[list[list[Any]], list[Any]]] = {}

    #: Whether :meth:`choose_subset` reads ω^t; methods that do not get ``None`` instead
    #: (building ω^t is a large share of a request's cost).
    observes: bool = True

    def default_name(self) -> str:
        return type(self).__name__

    def choose_subset(self, step: int, observation: Observation | None) -> tuple[int, ...]:
        """The server indices (0..n-1) to send step ``step``'s request to (non-empty).

        ``observation`` is ω^t, or None when the class sets ``observes = False``.
        """
        raise NotImplementedError(f"{type(self).__name__} must implement choose_subset")

    def request_completed(self, record: RequestRecord, observation: Observation | None) -> RequestRecord | None:
        """Called for every completed request with the ω^t its decision saw (override).

        Returns:
            None to keep ``record``, or a replacement (e.g. with the reward filled in).
        """
        return None

    # ------------------------------------------------------------------ YAFS plumbing
    def _resolve_processes(self, app_name: Any, alloc_des: dict[int, Any], alloc_module: dict) -> None:
        model = self.edge_model
        modules = alloc_module.get(app_name, {})
        by_node = {alloc_des[des]: des for des in modules.get(model.service_module, [])}
        missing = [node for node in model.server_nodes if node not in by_node]
        if missing:
            raise SelectionError(
                f"{self.name}: no {model.service_module!r} replica on edge servers {missing}; "
                "deploy it with EdgePlacement"
            )
        self._service_des = [by_node[node] for node in model.server_nodes]
        sinks = [des for des in modules.get(SINK_MODULE, []) if alloc_des.get(des) == model.user_node]
        if not sinks:
            raise SelectionError(f"{self.name}: no {SINK_MODULE!r} sink on the user node; deploy EdgePopulation")
        self._sink_des = sinks[0]

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):  # noqa: N803
        if self._service_des is None:
            self._resolve_processes(app_name, alloc_DES, alloc_module)
        model = self.edge_model
        if message.dst == model.service_module:
            step = model.begin_request(message.id)
            observation = model.observe(step) if self.observes else None
            chosen = self.choose_subset(step, observation)
            # Valid subsets recur (at most 2^n of them): validate and route each once.
            cached = self._request_routes.get(chosen) if type(chosen) is tuple else None
            if cached is None:
                servers = self._checked(chosen)
                cached = (servers, (model.request_paths(servers), [self._service_des[i] for i in servers]))
                if type(chosen) is tuple and all(type(i) is int for i in chosen):
                    self._request_routes[chosen] = cached
            self._pending[message.id] = (step, cached[0], observation)
            return cached[1]
        route = self._reply_routes.get(topology_src)
        if route is None:
            route = self._reply_routes[topology_src] = ([model.reply_path(topology_src)], [self._sink_des])
        return route

    def _checked(self, subset: tuple[int, ...]) -> tuple[int, ...]:
        servers = tuple(sorted(int(i) for i in subset))
        n = self.edge_model.n_servers
        if not servers or len(set(servers)) != len(servers) or servers[0] < 0 or servers[-1] >= n:
            raise SelectionError(f"{self.name}: invalid subset {subset!r} for {n} servers")
        return servers

    def on_request_complete(self, sim: Sim, outcome: RequestOutcome) -> None:
        pending = self._pending.pop(outcome.request_id, None)
        if pending is None:
            return
        step, servers, observation = pending
        model = self.edge_model
        first = outcome.first
        nan = math.nan
        if first is None:
            latency_s, winner = model.fallback_latency_s, -1
            upload_s = propagation_s = download_s = compute_s = nan
        else:
            winner = model.server_index(first.dst_node)
            latency_s = first.time_end - outcome.time_emit
            parts = model.copy_breakdown(outcome.request_id, winner)
            upload_s, propagation_s = parts.upload_s, parts.propagation_s
            download_s, compute_s = parts.download_s, parts.compute_s
        record = RequestRecord(
            method=self.name,
            step=step,
            request_id=outcome.request_id,
            time_emit_s=outcome.time_emit,
            latency_s=latency_s,
            target_s=model.target_latency_s(step),
            servers=servers,
            n_servers=model.n_servers,
            refused=outcome.refused,
            fallback=first is None,
            winner=winner,
            upload_s=upload_s,
            propagation_s=propagation_s,
            download_s=download_s,
            compute_s=compute_s,
        )
        record = self.request_completed(record, observation) or record
        self._on_record(record)
        model.forget_request(outcome.request_id)


def _check_x(x: int, n: int, method: str) -> int:
    if isinstance(x, bool) or not isinstance(x, int | np.integer) or not 1 <= x <= n:
        raise SelectionError(f"{method}: x must be an integer in 1..{n} (the number of servers), got {x!r}")
    return int(x)


class Oracle(SubsetSelection):
    """Every request to all n servers: the per-request lower bound on latency (§V-B i)."""

    observes = False

    def default_name(self) -> str:
        return "Oracle"

    def choose_subset(self, step: int, observation: Observation | None) -> tuple[int, ...]:
        return tuple(range(self.edge_model.n_servers))


class RandX(SubsetSelection):
    """x servers drawn uniformly without replacement per request (§V-B ii).

    Args:
        edge_model: the run's edge model.
        x: the redundancy level.
        rng: the method's seeded generator.
        **kwargs: see :class:`SubsetSelection`.
    """

    observes = False

    def __init__(self, edge_model: EdgeModel, x: int, rng: np.random.Generator, **kwargs: Any) -> None:
        self.x = _check_x(x, edge_model.n_servers, "Rand-x")
        self.rng = rng
        super().__init__(edge_model, **kwargs)

    def default_name(self) -> str:
        return f"Rand-{self.x}"

    def choose_subset(self, step: int, observation: Observation | None) -> tuple[int, ...]:
        return tuple(self.rng.choice(self.edge_model.n_servers, size=self.x, replace=False).tolist())


class MinLoadX(SubsetSelection):
    """The x servers with the fewest active users ℓ_i; ties broken at random (§V-B iv).

    Args:
        edge_model: the run's edge model.
        x: the redundancy level.
        rng: the generator that breaks ties.
        **kwargs: see :class:`SubsetSelection`.
    """

    def __init__(self, edge_model: EdgeModel, x: int, rng: np.random.Generator, **kwargs: Any) -> None:
        self.x = _check_x(x, edge_model.n_servers, "MinLoad-x")
        self.rng = rng
        super().__init__(edge_model, **kwargs)

    def default_name(self) -> str:
        return f"MinLoad-{self.x}"

    def choose_subset(self, step: int, observation: Observation) -> tuple[int, ...]:
        load = observation.server_active_users
        order = np.lexsort((self.rng.random(load.shape[0]), load))
        return tuple(order[: self.x].tolist())


class MinPropX(SubsetSelection):
    """The x servers with the lowest median propagation latency ρ^μ_i; ties by index (§V-B iii).

    Args:
        edge_model: the run's edge model.
        x: the redundancy level.
        **kwargs: see :class:`SubsetSelection`.
    """

    observes = False

    def __init__(self, edge_model: EdgeModel, x: int, **kwargs: Any) -> None:
        self.x = _check_x(x, edge_model.n_servers, "MinProp-x")
        super().__init__(edge_model, **kwargs)
        order = np.argsort(edge_model.world.median_propagation_s, kind="stable")
        self._subset = tuple(order[: self.x].tolist())

    def default_name(self) -> str:
        return f"MinProp-{self.x}"

    def choose_subset(self, step: int, observation: Observation | None) -> tuple[int, ...]:
        return self._subset


class SafeTailSelection(SubsetSelection):
    """SafeTail (§III): the learned policy picks each request's subset of edge servers.

    ``choose_subset`` encodes ω^t, asks the learner for an action (ε-greedy per Eq. 3 when
    ``explore``) and maps it to its subset; when the request completes, the Eq. 5 reward of
    L_R against τ goes into the record and, when ``learn``, back to the learner as the tuple
    (ω^t, A^{t+1}, R^{t+1}) (a training round every κ tuples).

    Args:
        edge_model: the run's edge model.
        learner: the :class:`~yafs_safetail.policy.learner.SafeTailLearner`.
        scales: the state normalisation (``StateScales.for_use_case``).
        explore: ε-greedy exploration (training phase) or always the argmax (testing).
        learn: feed completed requests back to the learner.
        **kwargs: see :class:`SubsetSelection`.

    Attributes:
        decision_time_s: wall time spent in encoding states and choosing actions.
        training_time_s: wall time spent in ``learner.observe`` (storing and training).
    """

    def __init__(self, edge_model: EdgeModel, learner: Any, scales: StateScales, *,
                 explore: bool, learn: bool, **kwargs: Any) -> None:
        if learner.n_servers != edge_model.n_servers:
            raise SelectionError(
                f"SafeTail: the policy is for {learner.n_servers} servers, the topology has "
                f"{edge_model.n_servers}"
            )
        super().__init__(edge_model, **kwargs)
        self.learner = learner
        self.scales = scales
        self.explore = explore
        self.learn = learn
        self.delta = learner.config.delta
        self.decision_time_s = 0.0
        self.training_time_s = 0.0
        self._decisions: dict[int, tuple[np.ndarray, int, float]] = {}

    def default_name(self) -> str:
        return "SafeTail"

    def choose_subset(self, step: int, observation: Observation) -> tuple[int, ...]:
        started = time.perf_counter()
        state = encode_state(observation, self.scales)
        epsilon = self.learner.epsilon if self.explore else 0.0
        action = self.learner.act(state, explore=self.explore)
        self._decisions[step] = (state, action, epsilon)
        subset = subset_of(action, self.edge_model.n_servers)
        self.decision_time_s += time.perf_counter() - started
        return subset

    def request_completed(self, record: RequestRecord, observation: Observation) -> RequestRecord:
        state, action, epsilon = self._decisions.pop(record.step)
        value = reward(record.latency_s, record.target_s, record.n_selected, record.n_servers,
                       self.delta)
        if self.learn:
            started = time.perf_counter()
            self.learner.observe(state, action, value)
            self.training_time_s += time.perf_counter() - started
        return dataclasses.replace(record, reward=value, epsilon=epsilon)


_BASELINE_PATTERN = re.compile(r"^(Oracle|Rand|MinLoad|MinProp)(?:-(\d+))?$")


def make_baseline(
    name: str,
    edge_model: EdgeModel,
    rng: np.random.Generator,
    on_record: Callable[[RequestRecord], None] | None = None,
) -> SubsetSelection:
    """A baseline from its name: ``"Oracle"``, ``"Rand-x"``, ``"MinLoad-x"``, ``"MinProp-x"``.

    Args:
        name: the method name.
        edge_model: the run's edge model.
        rng: the method's generator (Rand draws, MinLoad tie-breaks; unused otherwise).
        on_record: see :class:`SubsetSelection`.

    Raises:
        SelectionError: an unknown name or x outside 1..n.
    """
    match = _BASELINE_PATTERN.match(name)
    if match is None or (match.group(1) == "Oracle") != (match.group(2) is None):
        raise SelectionError(
            f"method: unknown baseline {name!r}; expected Oracle, Rand-x, MinLoad-x or MinProp-x"
        )
    kind = match.group(1)
    if kind == "Oracle":
        return Oracle(edge_model, on_record=on_record)
    x = int(match.group(2))
    if kind == "Rand":
        return RandX(edge_model, x, rng, on_record=on_record)
    if kind == "MinLoad":
        return MinLoadX(edge_model, x, rng, on_record=on_record)
    return MinPropX(edge_model, x, on_record=on_record)
