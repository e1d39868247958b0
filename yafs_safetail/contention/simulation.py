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

from yafs_safetail.contention.state import (
    CANCELLED,
    DONE,
    QUEUED,
    REFUSED,
    REPLYING,
    RUNNING,
    TRANSIT,
    Copy,
    Link,
    Request,
    Server,
    Transfer,
    outcome,
)
from yafs_safetail.contention.types import Dispatcher, EngineResult, EngineSettings, RequestBlock

#: A scheduled event: (time_s, sequence, handler, subject, version). The sequence number breaks
#: ties in scheduling order, so the handler is never compared; ``handler(subject, version)`` runs
#: it (the version lets a handler skip an event that a later one replaced).
Event = tuple[float, int, Callable[[Any, int], None], Any, int]

_push = heapq.heappush


class Simulation:
    """One run: the servers, the event heap, the requests being emitted and the result arrays.

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
        self.result = EngineResult(emit, np.full(n_requests, np.nan), np.zeros(n_requests, dtype=np.int64),
                                   np.zeros(n_requests, dtype=np.int64), np.zeros(n_requests, dtype=bool),
                                   np.full(n_requests, -1, dtype=np.int64))
        self.n_copies = self.result.n_copies
        self.emit_list: list[float] = emit.tolist()
        self.n_requests = n_requests
        self.next_request = 0
        self.block_size = block_size
        self.block = block
        self.block_index = -1
        self.tables: RequestBlock | None = None

    def run(self) -> EngineResult:
        """Emit every request at its time and handle events in time order until none is left."""
        self.start_background()
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
        result = self.result
        result.busy_s = self.busy_s
        result.cancelled_copies = self.cancelled_copies
        result.end_s = self.now_s
        return result

    def schedule(self, at_s: float, handler: Callable[[Any, int], None], subject: Any, version: int = 0) -> None:
        """``handler(subject, version)`` at ``at_s`` (after the events already due then)."""
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
        if not self.hedged:
            for index in chosen:
                self.send(request, index, tables, row)
            return
        self.send(request, chosen[0], tables, row)
        if len(chosen) > 1:
            request.unsent = [(index, tables, row) for index in chosen[1:]]
            delay_s = self.dispatcher.hedge_delay_s()
            # No timer for an infinite delay (the next copy then goes only if the first is
            # refused): an event at infinity would poison the servers' clocks.
            if delay_s < math.inf:
                self.schedule(self.now_s + delay_s, self.on_hedge_timer, request)

    def send(self, request: Request, index: int, tables: RequestBlock, row: int) -> None:
        """One copy of ``request`` to server ``index``; ``tables``' entry ``row`` is the request."""
        server = self.servers[index]
        levels = self.levels
        base = index * levels
        propagation_s = tables.propagation_s[row][index]
        # The output's transfer term is read when the copy finishes computing.
        copy = Copy(request, server, tables.work_s[row][index], propagation_s,
                    tables.output_transfer_s[row][base:base + levels])
        request.copies.append(copy)
        self.n_copies[request.index] += 1
        if self.shared_links:
            input_by_level = tables.input_transfer_s[row][base:base + levels]
            if any(input_by_level):
                self.start_transfer(copy, server.down, input_by_level)
                return
            input_s = 0.0  # nothing to send: the link is not used
        else:
            input_s = tables.input_transfer_s[row][base + self.level_of(server.active_users())]
            copy.input_s = input_s
        self.schedule(self.now_s + 2.0 * input_s + propagation_s, self.on_arrival, copy)

    def send_cancel(self, copy: Copy) -> None:
        self.schedule(self.now_s + copy.propagation_s, self.on_cancel, copy)

    def send_next_hedge(self, request: Request) -> None:
        if request.unsent:
            index, tables, row = request.unsent.pop(0)
            self.send(request, index, tables, row)

    def finish(self, request: Request, latency_s: float, copy: Copy | None) -> None:
        """``request`` ends with ``latency_s``: ``copy``'s reply, or the fallback (None)."""
        j = request.index
        request.done = True
        result = self.result
        result.latency_s[j] = latency_s
        result.refused[j] = request.refused
        if copy is None:
            result.fallback[j] = True
        else:
            result.winner[j] = copy.server.index
        if not self.wants_outcomes:
            return
        self.dispatcher.completed(outcome(request, latency_s, copy))

    # --- servers --------------------------------------------------------------------------------

    def start(self, server: Server, copy: Copy) -> None:
        """``copy`` takes a slot (the caller has advanced ``server`` and reschedules it)."""
        server.own += 1
        copy.state = RUNNING
        copy.start_s = self.now_s
        heapq.heappush(server.jobs, (server.virtual_s + copy.work_s, next(self.sequence), copy))
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
        if end_s is not None:
            self.schedule(end_s, self.on_service_end, server, server.version)

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
                return
            output_s = 0.0
        else:
            output_s = copy.output_by_level[self.level_of(server.active_users())]
        copy.output_s = output_s
        self.schedule(self.now_s + 2.0 * output_s + copy.propagation_s, self.on_reply, copy)

    # --- links ----------------------------------------------------------------------------------

    def start_transfer(self, copy: Copy, link: Link, time_by_level_s: list[float]) -> None:
        transfer = Transfer(copy, link, time_by_level_s, self.now_s, since_s=self.now_s)
        copy.transfer = transfer
        link.transfers.append(transfer)
        self.link_changed(link)

    def leave_link(self, transfer: Transfer) -> None:
        link = transfer.link
        link.transfers.remove(transfer)
        transfer.copy.transfer = None
        if link.transfers:
            self.link_changed(link)

    def link_changed(self, link: Link) -> None:
        """The link's number of transfers (or its server's background) changed: bring every
        transfer on it up to now at its old pace and reschedule its end at the new level."""
        now_s = self.now_s
        level = self.level_of(link.server.background + len(link.transfers) - 1)
        for transfer in link.transfers:
            self.schedule(transfer.rescale(now_s, level), self.on_transfer_end, transfer, transfer.version)

    def start_background(self) -> None:
        rows = self.settings.background
        if not rows:
            return
        for server in self.servers:
            server.background = rows[0][server.index]
        if math.isfinite(self.settings.background_period_s):
            self.schedule(self.settings.background_period_s, self.on_background_change, 1)

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
            self.busy_s += now_s - copy.start_s
            copy.state = REPLYING
            copy.end_s = now_s
            self.send_reply(copy)
        self.occupancy_changed(server)

    def on_arrival(self, copy: Copy, _: int) -> None:
        """``copy`` reaches its server: it runs, waits or is refused."""
        if copy.state == CANCELLED:
            return
        server = copy.server
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
                self.finish(request, self.settings.fallback_latency_s, None)

    def on_reply(self, copy: Copy, _: int) -> None:
        """``copy``'s reply reaches the user: the first one ends its request."""
        copy.state = DONE
        request = copy.request
        if request.done:
            return
        self.finish(request, self.now_s - request.emit_s, copy)
        request.unsent = None
        if self.settings.cancel:
            for other in request.copies:
                # (A reply still on its up link is cancelled too.)
                if other.state <= RUNNING or other.transfer is not None:
                    self.send_cancel(other)

    def on_cancel(self, copy: Copy, _: int) -> None:
        """A cancel message reaches ``copy``'s server (or its transfer)."""
        state = copy.state
        if state == TRANSIT or (state == REPLYING and copy.transfer is not None):
            # Still being sent (its input, or its reply on the up link): the transfer stops.
            if copy.transfer is not None:
                self.leave_link(copy.transfer)
            copy.state = CANCELLED
            self.cancelled_copies += 1
        elif state == QUEUED:
            copy.state = CANCELLED
            copy.server.waiting -= 1
            self.cancelled_copies += 1
        elif state == RUNNING:
            server = copy.server
            server.advance(self.now_s)
            copy.state = CANCELLED
            server.own -= 1
            self.busy_s += self.now_s - copy.start_s
            self.cancelled_copies += 1
            self.occupancy_changed(server)

    def on_transfer_end(self, transfer: Transfer, version: int) -> None:
        """``transfer`` has sent everything (unless a later change moved its end)."""
        copy = transfer.copy
        if version != transfer.version or copy.transfer is not transfer:
            return
        term_s = 0.5 * (self.now_s - transfer.started_s)  # one of Eq. 1's two equal transfer terms
        self.leave_link(transfer)
        if transfer.link.is_up:
            copy.output_s = term_s
            self.schedule(self.now_s + copy.propagation_s, self.on_reply, copy)
        else:
            copy.input_s = term_s
            self.schedule(self.now_s + copy.propagation_s, self.on_arrival, copy)

    def on_hedge_timer(self, request: Request, _: int) -> None:
        if not request.done:
            self.send_next_hedge(request)

    def on_background_change(self, period: int, _: int) -> None:
        """Background tenants take period ``period``'s values."""
        rows = self.settings.background
        row = rows[period % len(rows)]
        for server in self.servers:
            tenants = row[server.index]
            if tenants == server.background:
                continue
            server.advance(self.now_s)
            server.background = tenants
            self.occupancy_changed(server)
            if self.shared_links:
                for link in (server.down, server.up):
                    if link.transfers:
                        self.link_changed(link)
        # Background changes only matter while requests remain.
        if self.next_request < self.n_requests or self.events:
            self.schedule(self.now_s + self.settings.background_period_s, self.on_background_change, period + 1)
