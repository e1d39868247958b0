"""The contention engine's event loop (``contention.engine.run_engine`` is its entry point).

A :class:`Simulation` holds the servers and their links (``contention.state``), a heap of
events and the per-request result arrays. It emits each request at its time and handles the
events in time order; every event is a handler and its subject (a server, a copy, a transfer, a
request), and each ``on_*`` method is one kind of event, in the manner of a simpy process.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from yafs_safetail.contention.failure_handling import FailureHandling
from yafs_safetail.contention.shared_capacity import SharedCapacity
from yafs_safetail.contention.state import (
    CANCELLED,
    DONE,
    LOST,
    QUEUED,
    REFUSED,
    REPLYING,
    RUNNING,
    TRANSIT,
    Copy,
    Request,
    Server,
    first_reply,
)
from yafs_safetail.contention.types import (
    END_ALL_REFUSED_CODE,
    END_REPLY_CODE,
    Dispatcher,
    EngineResult,
    EngineSettings,
    RequestBlock,
)
from yafs_safetail.edge.failures import END_REASONS

#: A scheduled event: (time_s, sequence, handler, subject, version). The sequence number breaks
#: ties in scheduling order, so the handler is never compared; ``handler(subject, version)`` runs
#: it (the version lets a handler skip an event that a later one replaced).
Event = tuple[float, int, Callable[[Any, int], None], Any, int]

_push = heapq.heappush


class Simulation(FailureHandling, SharedCapacity):
    """One run: the servers, the event heap, the requests being emitted and the result arrays
    (failures, time-outs and energy in :class:`FailureHandling`; links and background tenants in
    :class:`SharedCapacity`).

    Each ``on_*`` method handles one kind of event at ``now_s``; the others are the steps they
    share (a copy starts, a server's occupancy or a link's transfers change, a request ends).
    """

    def __init__(self, settings: EngineSettings, emit: np.ndarray, block_size: int,
                 block: Callable[[int], RequestBlock], dispatcher: Dispatcher) -> None:
        self.settings = settings
        self.servers = [Server(i, spec.slots, spec.speed) for i, spec in enumerate(settings.servers)]
        self.levels = settings.contention_levels
        self.top_level = self.levels - 1
        self.queue_when_full = settings.queue
        self.shared_links = settings.shared_links
        self.dispatcher = dispatcher
        self.hedged = dispatcher.mode == "hedge"
        self.tied = dispatcher.mode == "tied"
        self.wants_outcomes = dispatcher.wants_outcomes
        self.events: list[Event] = []
        self.sequence = itertools.count()
        self.now_s = 0.0
        self.busy_s = 0.0
        self.cancelled_copies = 0
        n_requests = emit.shape[0]
        self.emit = emit
        self.emit_list: list[float] = emit.tolist()
        self.n_requests = n_requests
        self.next_request = 0
        self.block_size = block_size
        self.block = block
        self.block_index = -1
        self.tables: RequestBlock | None = None
        self.timeout_s = settings.timeout_s
        self.per_process_w = settings.per_process_w
        self.radio_up_j_per_byte = settings.radio_up_j_per_byte
        self.radio_down_j_per_byte = settings.radio_down_j_per_byte
        self.radio_active_w = settings.radio_active_w
        self.lost_copies = 0
        # Per-request results, energies included, as lists while the loop writes them (a list
        # item is several times cheaper to write than an array item, and every request writes
        # these); ``run`` turns them into the result's arrays.
        self.latency_s: list[float] = [math.nan] * n_requests
        self.n_copies: list[int] = [0] * n_requests
        self.refused: list[int] = [0] * n_requests
        self.fallback: list[bool] = [False] * n_requests
        self.winner: list[int] = [-1] * n_requests
        self.end_reason: list[int] = [END_REPLY_CODE] * n_requests
        self.lost: list[int] = [0] * n_requests
        self.server_energy_j = [0.0] * n_requests
        self.radio_energy_j = [0.0] * n_requests
        self.saved_energy_j = [0.0] * n_requests

    def run(self) -> EngineResult:
        """Emit every request at its time and handle events in time order until none is left."""
        self.start_background()
        self.schedule_outages()
        events = self.events
        pop = heapq.heappop
        emit_list = self.emit_list
        n_requests = self.n_requests
        next_emit = emit_list[0] if n_requests else math.inf
        while True:
            if self.next_request < n_requests and next_emit <= (events[0][0] if events else math.inf):
                self.now_s = next_emit
                j = self.next_request
                self.next_request = j + 1
                next_emit = emit_list[j + 1] if j + 1 < n_requests else math.inf
                self.emit_request(j)
                continue
            if not events:
                break
            self.now_s, _, handler, subject, version = pop(events)
            handler(subject, version)
        result = EngineResult(self.emit, np.asarray(self.latency_s, dtype=float),
                              np.asarray(self.n_copies, dtype=np.int64), np.asarray(self.refused, dtype=np.int64),
                              np.asarray(self.fallback, dtype=bool), np.asarray(self.winner, dtype=np.int64))
        result.end_reason = np.asarray(self.end_reason, dtype=np.int8)
        result.lost = np.asarray(self.lost, dtype=np.int64)
        result.busy_s = self.busy_s
        result.cancelled_copies = self.cancelled_copies
        result.end_s = self.now_s
        result.server_energy_j = np.asarray(self.server_energy_j, dtype=float)
        result.radio_energy_j = np.asarray(self.radio_energy_j, dtype=float)
        result.saved_energy_j = np.asarray(self.saved_energy_j, dtype=float)
        result.server_active_s = np.asarray([server.active_s for server in self.servers], dtype=float)
        result.lost_copies = self.lost_copies
        return result

    def schedule(self, at_s: float, handler: Callable[[Any, int], None], subject: Any, version: int = 0) -> None:
        """``handler(subject, version)`` at ``at_s`` (after the events already due then).

        The events of every transfer and service end are pushed where they arise, the same way
        (a call per event was a noticeable share of the loop's time)."""
        _push(self.events, (at_s, next(self.sequence), handler, subject, version))

    def level_of(self, users: int) -> int:
        """The contention level ``users`` other users make (the tables stop at the top one)."""
        return users if users < self.top_level else self.top_level

    # --- requests -------------------------------------------------------------------------------

    def emit_request(self, j: int) -> None:
        """Request ``j`` is emitted now: the dispatcher picks its servers and copies go out."""
        if j // self.block_size != self.block_index:
            self.block_index = j // self.block_size
            self.tables = self.block(self.block_index)
        tables = self.tables
        assert tables is not None
        row = j - tables.first
        # (Server.active_users inlined: this runs once per server per request.)
        chosen = list(self.dispatcher.choose(j, [s.own + s.waiting + s.background for s in self.servers]))
        request = Request(j, self.now_s)
        if tables.input_bytes:
            request.input_bytes = tables.input_bytes[row]
            request.output_bytes = tables.output_bytes[row]
        if not self.hedged:
            for index in chosen:
                self.send(request, index, tables, row)
        else:
            self.send(request, chosen[0], tables, row)
            if len(chosen) > 1:
                request.unsent = [(index, tables, row) for index in chosen[1:]]
                delay_s = self.dispatcher.hedge_delay_s()
                # No timer for an infinite delay (the next copy then goes only if the first is
                # refused): an event at infinity would poison the servers' clocks.
                if delay_s < math.inf:
                    self.schedule(self.now_s + delay_s, self.on_hedge_timer, request)
        # (No event without a time-out: with failures off the event order is the paper world's.)
        if self.timeout_s < math.inf:
            self.schedule(self.now_s + self.timeout_s, self.on_timeout, request)

    def send(self, request: Request, index: int, tables: RequestBlock, row: int) -> None:
        """One copy of ``request`` to server ``index``; ``tables``' entry ``row`` is the request."""
        server = self.servers[index]
        levels = self.levels
        base = index * levels
        propagation_s = tables.propagation_s[row][index]
        # The output's transfer term is read when the copy finishes computing.
        copy = Copy(request, server, tables.work_s[row][index], propagation_s,
                    tables.output_transfer_s[row][base:base + levels])
        copy.sent_s = self.now_s
        request.copies.append(copy)
        self.n_copies[request.index] += 1
        if server.is_down:
            # The user does not know: its device sends the input (as if alone on the link), and
            # nothing will ever answer.
            input_s = tables.input_transfer_s[row][base + self.level_of(server.background)]
            self.charge_upload(request, 1.0, 2.0 * input_s)
            self.lose(copy)
            return
        if self.shared_links:
            input_by_level = tables.input_transfer_s[row][base:base + levels]
            if any(input_by_level):
                self.start_transfer(copy, server.down, input_by_level)
                return  # its upload is charged when the transfer ends or stops
            input_s = 0.0  # nothing to send: the link is not used
        else:
            input_s = tables.input_transfer_s[row][base + self.level_of(server.active_users())]
            copy.input_s = input_s
        # (At start, a transfer's time is fixed when it starts and nothing stops it.)
        self.charge_upload(request, 1.0, 2.0 * input_s)
        self.schedule(self.now_s + 2.0 * input_s + propagation_s, self.on_arrival, copy)

    def send_cancel(self, copy: Copy) -> None:
        self.schedule(self.now_s + copy.propagation_s, self.on_cancel, copy)

    def cancel_others(self, request: Request) -> None:
        """Cancel every copy of ``request`` that may still compute or send (cancel semantics)."""
        for other in request.copies:
            # (A reply still on its up link is cancelled too.)
            if other.state <= RUNNING or other.transfer is not None:
                self.send_cancel(other)

    def send_next_hedge(self, request: Request) -> None:
        if request.unsent:
            index, tables, row = request.unsent.pop(0)
            self.send(request, index, tables, row)

    def finish(self, request: Request, latency_s: float, copy: Copy | None,
               reason: int = END_REPLY_CODE) -> None:
        """``request`` ends with ``latency_s``: ``copy``'s reply, or the fallback (None), for
        ``reason`` (an index into ``END_REASONS``)."""
        j = request.index
        request.done = True
        self.latency_s[j] = latency_s
        self.refused[j] = request.refused
        if reason != END_REPLY_CODE:
            self.end_reason[j] = reason
        if copy is None:
            self.fallback[j] = True
        else:
            self.winner[j] = copy.server.index
        if not self.wants_outcomes:
            return
        self.dispatcher.completed(first_reply(request, latency_s, copy, END_REASONS[reason],
                                              self.energy_so_far(request)))

    # --- servers --------------------------------------------------------------------------------

    def start(self, server: Server, copy: Copy) -> None:
        """``copy`` takes a slot (the caller has advanced ``server`` and reschedules it)."""
        server.own += 1
        copy.state = RUNNING
        copy.start_s = self.now_s
        copy.finish_virtual_s = finish_virtual_s = server.virtual_s + copy.work_s
        heapq.heappush(server.jobs, (finish_virtual_s, next(self.sequence), copy))
        request = copy.request
        if self.tied and not request.tied:
            # Only the first copy to start cancels its siblings; a sibling that starts before
            # the cancellation reaches it runs until it does (both cancelling would lose both).
            request.tied = True
            for other in request.copies:
                if other is not copy and other.state <= RUNNING:
                    self.send_cancel(other)

    def reschedule(self, server: Server) -> None:
        """Schedule the server's next completion at its current speed (earlier ones go stale)."""
        end_s = server.next_end_s(self.now_s)
        if end_s is not None:  # (schedule, inlined: see there)
            _push(self.events, (end_s, next(self.sequence), self.on_service_end, server, server.version))

    def occupancy_changed(self, server: Server) -> None:
        """Occupancy changed (server advanced to now): waiting copies may start, and the next
        completion moves."""
        if self.queue_when_full:
            queue = server.queue
            while queue and server.own + server.background < server.slots:
                copy = queue.popleft()
                if copy.state == QUEUED:
                    server.waiting -= 1
                    self.start(server, copy)
        self.reschedule(server)

    def send_reply(self, copy: Copy) -> None:
        """``copy`` has finished computing: its reply leaves for the user."""
        server = copy.server
        if self.shared_links:
            if any(copy.output_by_level):
                self.start_transfer(copy, server.up, copy.output_by_level)
                return  # its download is charged when the transfer ends or stops
            output_s = 0.0
        else:
            output_s = copy.output_by_level[self.level_of(server.active_users())]
        copy.output_s = output_s
        copy.reply_left_s = self.now_s + 2.0 * output_s
        self.charge_download(copy.request, 1.0, 2.0 * output_s)
        self.schedule(self.now_s + 2.0 * output_s + copy.propagation_s, self.on_reply, copy)

    # --- events ---------------------------------------------------------------------------------

    def on_service_end(self, server: Server, version: int) -> None:
        """The server's first job (maybe several, at equal times) has received its work."""
        if version != server.version:
            return
        now_s = self.now_s
        server.advance(now_s)
        jobs = server.jobs
        limit = server.virtual_s + 1e-9 * (1.0 + abs(server.virtual_s))
        while jobs and (jobs[0][2].state != RUNNING or jobs[0][0] <= limit):
            copy = heapq.heappop(jobs)[2]
            if copy.state != RUNNING:
                continue
            server.own -= 1
            self.stop_computing(copy)
            copy.state = REPLYING
            copy.end_s = now_s
            self.send_reply(copy)
        self.occupancy_changed(server)

    def on_arrival(self, copy: Copy, _: int) -> None:
        """``copy`` reaches its server: it runs, waits or is refused (or is lost)."""
        state = copy.state
        if state == CANCELLED or state == LOST:
            return
        server = copy.server
        if server.down_starts_s and (server.is_down or server.went_down_within(copy.sent_s, self.now_s)):
            self.lose(copy)
            return
        copy.arrive_s = self.now_s
        if server.own + server.background < server.slots and not (self.queue_when_full and server.waiting):
            server.advance(self.now_s)
            self.start(server, copy)
            self.reschedule(server)
        elif self.queue_when_full:
            copy.state = QUEUED
            server.waiting += 1
            server.queue.append(copy)
        else:
            copy.state = REFUSED
            request = copy.request
            request.refused += 1
            if request.done:
                return
            if self.hedged and request.unsent:
                self.send_next_hedge(request)
            elif all(c.state == REFUSED for c in request.copies) and not request.unsent:
                self.finish(request, self.settings.fallback_latency_s, None, END_ALL_REFUSED_CODE)

    def on_reply(self, copy: Copy, _: int) -> None:
        """``copy``'s reply reaches the user: the first one ends its request."""
        if copy.state == LOST or (copy.server.down_starts_s and self.lost_on_the_way(copy)):
            if copy.state != LOST:
                self.lose(copy)
            return
        copy.state = DONE
        request = copy.request
        if request.done:
            return
        self.finish(request, self.now_s - request.emit_s, copy)
        request.unsent = None
        if self.settings.cancel:
            self.cancel_others(request)

    def on_cancel(self, copy: Copy, _: int) -> None:
        """A cancel message reaches ``copy``'s server (or its transfer)."""
        state = copy.state
        # A cancelled copy saves the compute it had left, at its server's one-job speed: all of
        # its work if it had not started.
        saved_j = self.per_process_w / copy.server.speed[1]
        if state == TRANSIT or (state == REPLYING and copy.transfer is not None):
            # Still being sent (its input, or its reply on the up link): the transfer stops.
            transfer = copy.transfer
            if transfer is not None:
                self.charge_stopped(transfer)
                self.leave_link(transfer)
            elif copy.server.down_starts_s and self.lost_on_the_way(copy):
                self.lose(copy)  # its server failed after it left: the cancel finds nothing
                return
            copy.state = CANCELLED
            self.cancelled_copies += 1
            if state == TRANSIT:
                self.saved_energy_j[copy.request.index] += saved_j * copy.work_s
        elif state == QUEUED:
            copy.state = CANCELLED
            copy.server.waiting -= 1
            self.cancelled_copies += 1
            self.saved_energy_j[copy.request.index] += saved_j * copy.work_s
        elif state == RUNNING:
            server = copy.server
            server.advance(self.now_s)
            copy.state = CANCELLED
            server.own -= 1
            self.stop_computing(copy)
            self.cancelled_copies += 1
            self.saved_energy_j[copy.request.index] += saved_j * max(0.0, copy.finish_virtual_s - server.virtual_s)
            self.occupancy_changed(server)

    def on_hedge_timer(self, request: Request, _: int) -> None:
        if not request.done:
            self.send_next_hedge(request)
