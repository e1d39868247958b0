"""EdgeModel: the SafeTail edge world plugged into the core's delay hooks.

One :class:`EdgeModel` per simulation run: it holds the run's mutable state (the project's
own copies running on each server, each copy's Eq. 1 terms) on top of a shared, read-only
:class:`~yafs_safetail.edge.world.EdgeWorld`.

A copy of the request of step *t* sent to server *i* travels user -> access point -> server
and back. The hooks charge Eq. 1 term by term:

====================  ==============================================================
hop / service         delay
====================  ==============================================================
user -> AP            input uploading, Size(I) / min(λ^d_i, Λ^u)
AP -> server          ρ_i + input downloading (the same transfer time again)
service               compute time at k = ℓ_i + 1 processes (refused when ℓ_i >= max load)
server -> AP          output uploading, Size(O) / min(λ^u_i, Λ^d), + ρ_i
AP -> user            output downloading (the same transfer time again)
====================  ==============================================================

The bandwidths are fixed when the copy leaves the user, from the pool of the server's
contention level min(ℓ_i, 4) (ℓ_i = active users already on the server: the WiFi is shared
equally among them), so the input and output transfers of one copy use one bandwidth draw.
``uses_link_queues`` is False and ``concurrent`` is True: in the paper's model copies never
wait for each other (Eq. 1 has no waiting term; assumption ii).

Failures and energy (docs/failures_energy.md): with the world's ``down_intervals`` a copy whose
server is down when it arrives is lost at once (the core sees a refusal, the record counts it as
lost), and one whose server goes down before its compute ends holds its process until then and
sends no reply (its reply finds no route: the core's ``"lost"``). Every copy's energy is
counted once, when its request ends (:meth:`EdgeModel.request_fates`): its server's marginal
power over the time it computed, the device's radio for its upload and for the download of
every reply that reached the user. (tests/test_energy_edge.py checks these sums against
totals kept apart by an instrumented subclass, not here, off the per-copy path.)

Request -> step: the n-th request the user emits is step n of the world (its request, trace
row and draws), whichever selection routes it; with the default one request per
``step_interval_s`` this is also the request's minute in the load trace.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from yafs_safetail.edge.latency import CopyLatency
from yafs_safetail.edge.observation import Observation
from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.yafs.application import Application, Message

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim

#: Module and message names of the edge application (see :func:`edge_application`).
SOURCE_MODULE = "User"
SINK_MODULE = "UserSink"
REQUEST_MESSAGE = "Request"
REPLY_MESSAGE = "Reply"


def edge_application(app_name: str, service_module: str) -> Application:
    """The SafeTail application as a YAFS :class:`Application`.

    The user's source emits ``Request`` to ``service_module``; the service answers with
    ``Reply`` to the user's sink. Message bytes and instructions are YAFS placeholders: the
    edge model computes every delay from the world (sizes, bandwidths, compute model).
    """
    app = Application(name=app_name)
    app.set_modules(
        [
            {SOURCE_MODULE: {"Type": Application.TYPE_SOURCE}},
            {service_module: {"RAM": 1, "Type": Application.TYPE_MODULE}},
            {SINK_MODULE: {"Type": Application.TYPE_SINK}},
        ]
    )
    request = Message(REQUEST_MESSAGE, SOURCE_MODULE, service_module, instructions=0, bytes=0)
    reply = Message(REPLY_MESSAGE, service_module, SINK_MODULE, instructions=0, bytes=0)
    app.add_source_messages(request)
    app.add_service_module(service_module, request, reply)
    return app


class EdgeModelError(RuntimeError):
    """The simulation went beyond what the world was drawn for, or routed off the topology."""


class _CopyState:
    """The Eq. 1 terms of one copy, filled in as it travels, and what became of it.

    ``served_s`` is the time it held a server process: its compute time, or until its server
    failed (0 when refused or lost on arrival). ``lost``: its server failed before its reply
    left; ``lost_on_arrival``: the server was down when it arrived (the core saw a refusal).
    """

    __slots__ = ("step", "server", "input_s", "output_s", "rtt_s", "compute_s", "refused",
                 "served_s", "lost", "lost_on_arrival")

    def __init__(self, step: int, server: int, input_s: float, output_s: float, rtt_s: float) -> None:
        self.step = step
        self.server = server
        self.input_s = input_s
        self.output_s = output_s
        self.rtt_s = rtt_s
        self.compute_s = float("nan")
        self.refused = False
        self.served_s = 0.0
        self.lost = False
        self.lost_on_arrival = False


class CopyFates:
    """What became of one request's copies, and what they cost (:meth:`EdgeModel.request_fates`).

    Attributes:
        lost: copies lost to a failed server (on arrival or while computing).
        lost_on_arrival: those of them the core counted as refused (the server was down).
        server_energy_j: the servers' marginal energy of every copy (per process power x the
            time it computed).
        radio_energy_j: the device's radio: every copy's upload, every received reply's download.
    """

    __slots__ = ("lost", "lost_on_arrival", "server_energy_j", "radio_energy_j")

    def __init__(self, lost: int, lost_on_arrival: int, server_energy_j: float,
                 radio_energy_j: float) -> None:
        self.lost = lost
        self.lost_on_arrival = lost_on_arrival
        self.server_energy_j = server_energy_j
        self.radio_energy_j = radio_energy_j


class EdgeModel:
    """The core's :class:`LinkDelay` and :class:`ServiceModel` for the SafeTail edge world.

    Args:
        world: the phase's pre-drawn world (shared between methods; read-only).

    Attributes:
        world: the world.
        n_servers: number of edge servers.
        server_nodes: edge server node ids in server index order.
        user_node: the user's node id.
        access_point_node: the access point's node id.
        app_name: the application name (from the placement).
        service_module: the service module name (from the placement).
        fallback_latency_s: the on-device fallback latency of the use case.
        timeout_s: how long the user waits for a first reply (``inf`` with failures off).
        requests_seen: number of requests mapped to steps so far.
    """

    uses_link_queues = False
    concurrent = True

    def __init__(self, world: EdgeWorld) -> None:
        self.world = world
        scenario = world.scenario
        self.n_servers = scenario.n_servers
        self.server_nodes: tuple[Any, ...] = scenario.server_nodes
        self.user_node = scenario.user_node
        self.access_point_node = scenario.access_point_node
        self.app_name = scenario.app_name
        self.service_module = scenario.module_name
        self.fallback_latency_s = world.fallback_latency_s
        self.timeout_s = world.timeout_s
        self.requests_seen = 0
        self._server_of_node = {node: index for index, node in enumerate(self.server_nodes)}
        # A list, not an array: it is read and updated per copy, where NumPy scalars are slow.
        self._own_running = [0] * self.n_servers
        self._step_of_request: dict[Any, int] = {}
        # Per request id: each server index's copy state (None: no copy sent there).
        # A request's copies by server; a slot stays None until that server's copy is
        # dispatched, and the hop and service hooks only ever read dispatched slots.
        self._copies: dict[Any, list[_CopyState]] = {}
        self._request_paths = [
            [self.user_node, self.access_point_node, node] for node in self.server_nodes
        ]
        self._reply_paths = [
            [node, self.access_point_node, self.user_node] for node in self.server_nodes
        ]
        tables = world.hop_tables
        self._background = tables.background_users
        self._input_transfer = tables.input_transfer_s
        self._output_transfer = tables.output_transfer_s
        self._rtt = tables.rtt_s
        self._compute = tables.compute_s
        self._target = tables.target_s
        self._input_bytes = tables.input_bytes
        self._output_bytes = tables.output_bytes
        self._levels = world.n_contention_levels
        self._max_load = world.max_load
        self._compute_width = world.compute_by_processes_s.shape[2]
        self._n_steps = world.n_steps
        self._down = world.down_intervals
        self._per_process_w = world.energy.server.per_process_w
        self._radio = world.energy.radio

    # ------------------------------------------------------------------ requests and steps
    def begin_request(self, request_id: Any) -> int:
        """The step of request ``request_id``; the first call for an id assigns the next step.

        Raises:
            EdgeModelError: more requests than the world has steps.
        """
        step = self._step_of_request.get(request_id)
        if step is None:
            step = self.requests_seen
            if step >= self._n_steps:
                raise EdgeModelError(
                    f"request {request_id!r} would be step {step}, but the world was drawn for "
                    f"{self.world.n_steps} steps; build it with more steps or run the Sim shorter"
                )
            self._step_of_request[request_id] = step
            self.requests_seen += 1
        return step

    @property
    def copies_running(self) -> int:
        """The project's own copies holding a server process now."""
        return sum(self._own_running)

    def observe(self, step: int) -> Observation:
        """ω^t: the servers' state when step ``step``'s request is issued (now)."""
        return self.world.observation(step, self.world.background_users[step] + self._own_running)

    def target_latency_s(self, step: int) -> float:
        """τ of Eq. 4 for step ``step``'s request."""
        return self._target[step]

    # ------------------------------------------------------------------ routing helpers
    def server_index(self, node: Any) -> int:
        """Server index of an edge server node id."""
        return self._server_of_node[node]

    def request_paths(self, subset: tuple[int, ...]) -> list[list[Any]]:
        """YAFS paths user -> AP -> server for each server index in ``subset``."""
        return [list(self._request_paths[i]) for i in subset]

    def reply_path(self, server_node: Any) -> list[Any]:
        """YAFS path server -> AP -> user for a reply leaving ``server_node``."""
        return list(self._reply_paths[self._server_of_node[server_node]])

    # ------------------------------------------------------------------ Eq. 1 records
    def copy_breakdown(self, request_id: Any, server: int) -> CopyLatency | None:
        """The Eq. 1 terms of the copy of ``request_id`` sent to server index ``server``.

        Returns None for a copy that was refused or never sent.
        """
        state = self._copy_state(request_id, server)
        if state is None:
            return None
        return CopyLatency(
            input_upload_s=state.input_s,
            input_download_s=state.input_s,
            input_propagation_s=state.rtt_s,
            compute_s=state.compute_s,
            output_upload_s=state.output_s,
            output_propagation_s=state.rtt_s,
            output_download_s=state.output_s,
        )

    def _copy_state(self, request_id: Any, server: int) -> _CopyState | None:
        states = self._copies.get(request_id)
        state: _CopyState | None = (
            None if states is None or not 0 <= server < self.n_servers else states[server])
        return None if state is None or state.refused else state

    def copy_lost(self, request_id: Any, server_node: Any) -> bool:
        """Whether the copy of ``request_id`` on ``server_node`` was lost to a failure (its
        reply must not be sent)."""
        states = self._copies.get(request_id)
        state = None if states is None else states[self._server_of_node[server_node]]
        return state is not None and state.lost

    def request_fates(self, request_id: Any) -> CopyFates:
        """What became of every copy of ``request_id``, and their energy (call before
        :meth:`forget_request`)."""
        lost = lost_on_arrival = 0
        server_energy_j = radio_energy_j = 0.0
        radio = self._radio
        for state in self._copies.get(request_id, ()):
            if state is None:
                continue
            radio_energy_j += radio.upload_energy_j(self._input_bytes[state.step], state.input_s)
            if state.lost:
                lost += 1
                lost_on_arrival += state.lost_on_arrival
            elif not state.refused:
                radio_energy_j += radio.download_energy_j(self._output_bytes[state.step], state.output_s)
            server_energy_j += self._per_process_w * state.served_s
        return CopyFates(lost, lost_on_arrival, server_energy_j, radio_energy_j)

    def forget_request(self, request_id: Any) -> None:
        """Drop the per-copy records of a completed request (keeps memory flat on long runs)."""
        self._copies.pop(request_id, None)
        self._step_of_request.pop(request_id, None)

    # ------------------------------------------------------------------ LinkDelay hook
    def _dispatch(self, message: Message, server: int) -> _CopyState:
        request_id = message.id
        step = self._step_of_request.get(request_id)
        if step is None:
            step = self.begin_request(request_id)
        others = self._background[step][server] + self._own_running[server]
        level = others if others < self._levels else self._levels - 1
        column = server * self._levels + level
        state = _CopyState(
            step,
            server,
            self._input_transfer[step][column],
            self._output_transfer[step][column],
            self._rtt[step][server],
        )
        states = self._copies.get(request_id)
        if states is None:
            states = self._copies[request_id] = [None] * self.n_servers  # type: ignore[list-item]
        states[server] = state
        return state

    def hop_delay_s(self, sim: Sim, message: Message, src_node: Any, dst_node: Any) -> float:
        """Eq. 1's term for this hop (see the module docstring)."""
        if src_node == self.user_node:
            return self._dispatch(message, self._server_of_node[message.copy_dst_node]).input_s
        if src_node == self.access_point_node:
            if dst_node == self.user_node:
                server = self._server_of_node[message.copy_dst_node]
                return self._copies[message.id][server].output_s
            state = self._copies[message.id][self._server_of_node[dst_node]]
            return state.rtt_s + state.input_s
        source_server = self._server_of_node.get(src_node)
        if source_server is None or dst_node != self.access_point_node:
            raise EdgeModelError(f"hop {src_node!r} -> {dst_node!r} is not on a user-AP-server path")
        state = self._copies[message.id][source_server]
        return state.output_s + state.rtt_s

    # ------------------------------------------------------------------ ServiceModel hooks
    def admit(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> bool:
        """Lose the copy when its server is down; refuse it when the server already has
        ``max_load`` active users; else start a process (until its compute ends, or its
        server fails first)."""
        server = self._server_of_node[node]
        state = self._copies[message.id][server]
        down = self._down
        if down is not None and down.is_down(server, sim.env.now):
            # A server that is down cannot refuse: the copy is lost, and the user never hears.
            state.lost = state.lost_on_arrival = True
            return False
        active = self._background[state.step][server] + self._own_running[server]
        if active >= self._max_load:
            state.refused = True
            return False
        self._own_running[server] += 1
        state.compute_s = state.served_s = self._compute[state.step][server * self._compute_width + active]
        if down is not None:
            now_s = sim.env.now
            failed_s = down.first_failure_s(server, now_s, now_s + state.compute_s)
            if failed_s is not None:
                state.lost = True
                state.served_s = failed_s - now_s
        return True

    def service_time_s(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> float:
        """The compute time fixed at admission (k = ℓ_i + 1 processes), or the time until the
        server fails."""
        return self._copies[message.id][self._server_of_node[node]].served_s

    def release(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> None:
        """The copy's process ends (or its server failed): one active user fewer on the server."""
        self._own_running[self._server_of_node[node]] -= 1
