"""The YAFS Selection that drives any policy: one request -> the policy's subset -> one copy per
chosen server -> the first reply -> a :class:`~yafs_safetail.record.RequestRecord`.

Why a request ended (``end_reason``, docs/failures_energy.md): a first reply within the world's
time-out ends it (``"reply"``, latency as Eq. 2). Otherwise the user takes the on-device
fallback: at once when every copy was refused (``"all_refused"``, the paper's rule), else
after the time-out (``"all_lost"`` when every copy not refused was lost to a failed server,
``"timeout"`` otherwise), so its latency is the time-out plus the fallback's. With failures off
the time-out is infinite and nothing is lost: every record is the paper's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from yafs_safetail.edge.failures import END_ALL_LOST, END_ALL_REFUSED, END_REPLY, END_TIMEOUT
from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.policy import (
    DispatchSupport,
    Policy,
    PolicyError,
    check_dispatch,
    checked_choice,
    name_a_users_failure,
)
from yafs_safetail.record import RequestRecord
from yafs_safetail.sim.hooks import SINK_MODULE, EdgeModel
from yafs_safetail.yafs.selection import Selection

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim
    from yafs_safetail.yafs.outcomes import RequestOutcome


#: The single-user world sends every chosen copy at once.
DISPATCH = DispatchSupport("the single-user world", ("all",),
                           elsewhere="the contention world (yafs-safetail sweep)")


def checked_subset(subset: Sequence[int], n_servers: int, name: str) -> tuple[int, ...]:
    """``subset`` as ascending Python ints, or PolicyError naming the method and the subset."""
    return tuple(sorted(checked_choice(subset, n_servers, name)))


class PolicySelection(Selection):
    """A YAFS :class:`Selection` that sends each request to the subset a :class:`Policy` chooses.

    It maps the request to its world step, builds ω^t (unless the policy does not observe),
    asks ``policy.choose``, returns one user -> AP -> server path per chosen server (redundant
    dispatch: one copy each), routes every reply to the user's sink, and, once every copy has
    settled, builds the request's record (L_R = the first reply, Eq. 2, or the on-device
    fallback when every copy was refused), passes it to ``policy.feedback`` and then to
    ``on_record``.

    Args:
        edge_model: the run's edge model (the Sim's link-delay and service hooks).
        policy: the method.
        on_record: called with every record; when None, records are appended to :attr:`records`.

    Attributes:
        records: the collected records (when no ``on_record`` is given).
        name: the policy's name.
    """

    def __init__(self, edge_model: EdgeModel, policy: Policy,
                 on_record: Callable[[RequestRecord], None] | None = None) -> None:
        super().__init__()
        check_dispatch(policy, DISPATCH)
        self.edge_model = edge_model
        self.policy = policy
        self.name = policy.name
        self.records: list[RequestRecord] = []
        #: Added to the core's request ids in the records (a simulation resumed mid-phase).
        self.request_id_offset = 0
        self._on_record = on_record if on_record is not None else self.records.append
        self._pending: dict[Any, tuple[int, tuple[int, ...]]] = {}
        self._service_des: list[Any] | None = None
        self._sink_des: Any = None
        # Routes are fixed per subset (requests) and per server node (replies): build each once.
        self._request_routes: dict[tuple[int, ...], tuple[tuple[int, ...], tuple[list[list[Any]], list[Any]]]] = {}
        self._reply_routes: dict[Any, tuple[list[list[Any]], list[Any]]] = {}
        # Only copies on servers that can fail are ever lost: without failures, no look-up per reply.
        self._copies_can_be_lost = edge_model.world.down_intervals is not None

    def _resolve_processes(self, app_name: Any, alloc_des: dict[int, Any], alloc_module: dict[Any, Any]) -> None:
        model = self.edge_model
        modules = alloc_module.get(app_name, {})
        by_node = {alloc_des[des]: des for des in modules.get(model.service_module, [])}
        missing = [node for node in model.server_nodes if node not in by_node]
        if missing:
            raise PolicyError(
                f"{self.name}: no {model.service_module!r} replica on edge servers {missing}; "
                "deploy it with EdgePlacement"
            )
        self._service_des = [by_node[node] for node in model.server_nodes]
        sinks = [des for des in modules.get(SINK_MODULE, []) if alloc_des.get(des) == model.user_node]
        if not sinks:
            raise PolicyError(f"{self.name}: no {SINK_MODULE!r} sink on the user node; deploy EdgePopulation")
        self._sink_des = sinks[0]

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):  # noqa: N803
        if self._service_des is None:
            self._resolve_processes(app_name, alloc_DES, alloc_module)
        model = self.edge_model
        if message.dst == model.service_module:
            step = model.begin_request(message.id)
            observation: Observation | None = model.observe(step) if self.policy.observes else None
            try:
                chosen = self.policy.choose(observation)
            except Exception as error:
                name_a_users_failure(self.policy, error, f"request {step + 1} of its phase")
                raise
            # Valid subsets recur (at most 2^n of them): validate and route each once.
            cached = self._request_routes.get(chosen) if type(chosen) is tuple else None
            if cached is None:
                servers = checked_subset(chosen, model.n_servers, self.name)
                assert self._service_des is not None
                cached = (servers, (model.request_paths(servers), [self._service_des[i] for i in servers]))
                if type(chosen) is tuple and all(type(i) is int for i in chosen):
                    self._request_routes[chosen] = cached
            self._pending[message.id] = (step, cached[0])
            return cached[1]
        if self._copies_can_be_lost and model.copy_lost(message.id, topology_src):
            return [], []  # its server failed before the reply left: the user never hears of it
        route = self._reply_routes.get(topology_src)
        if route is None:
            route = self._reply_routes[topology_src] = ([model.reply_path(topology_src)], [self._sink_des])
        return route

    @property
    def pending_requests(self) -> int:
        """Requests dispatched whose record is not built yet."""
        return len(self._pending)

    def on_request_complete(self, sim: Sim, outcome: RequestOutcome) -> None:
        pending = self._pending.pop(outcome.request_id, None)
        if pending is None:
            return
        step, servers = pending
        model = self.edge_model
        fates = model.request_fates(outcome.request_id)
        refused = outcome.refused - fates.lost_on_arrival
        first = outcome.first
        timeout_s = model.timeout_s
        if first is not None and first.time_end - outcome.time_emit > timeout_s:
            first = None  # the user gave up before this reply came
        nan = math.nan
        if first is None:
            winner = -1
            upload_s = propagation_s = download_s = compute_s = nan
            if refused == len(servers):
                end_reason, latency_s = END_ALL_REFUSED, model.fallback_latency_s
            else:
                end_reason = END_ALL_LOST if fates.lost == len(servers) - refused else END_TIMEOUT
                latency_s = timeout_s + model.fallback_latency_s
        else:
            end_reason = END_REPLY
            winner = model.server_index(first.dst_node)
            latency_s = first.time_end - outcome.time_emit
            parts = model.copy_breakdown(outcome.request_id, winner)
            assert parts is not None
            upload_s, propagation_s = parts.upload_s, parts.propagation_s
            download_s, compute_s = parts.download_s, parts.compute_s
        record = RequestRecord(
            method=self.name,
            step=step,
            request_id=outcome.request_id + self.request_id_offset,
            time_emit_s=outcome.time_emit,
            latency_s=latency_s,
            target_s=model.target_latency_s(step),
            servers=servers,
            n_servers=model.n_servers,
            refused=refused,
            fallback=first is None,
            winner=winner,
            upload_s=upload_s,
            propagation_s=propagation_s,
            download_s=download_s,
            compute_s=compute_s,
            lost=fates.lost,
            end_reason=end_reason,
            server_energy_j=fates.server_energy_j,
            radio_energy_j=fates.radio_energy_j,
            # Copies in this world are never cancelled: nothing is saved.
            saved_energy_j=0.0,
        )
        record = self.policy.feedback(record) or record
        self._on_record(record)
        model.forget_request(outcome.request_id)
