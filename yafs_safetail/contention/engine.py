"""The contention world's event loop: many users' copies sharing edge servers.

This module knows nothing of traces, use cases or policies. It sees

* servers: a number of slots each, a per-job speed for every occupancy (processor sharing: the
  running jobs split the server equally, so each progresses at ``speed[n]`` when ``n`` jobs run),
  and either refusal when the slots are full (the paper) or a FIFO waiting queue;
* links: each server's down link (inputs) and up link (outputs). With ``shared_links`` (the
  default) a transfer is processor-shared over its whole duration: it progresses at 1/T(L) of
  itself per second, T(L) being its transfer time at contention level L = the server's
  background tenants plus the other transfers on that link *now*, so every transfer that starts
  or ends on a link moves the end of the others there. Otherwise a transfer takes T(L) at the
  level when it starts, L counting every active user at the server (the single-user world's
  reading);
* requests: an emission time and, per server, the copy's delays and work (``RequestBlock``);
* a :class:`Dispatcher` that picks the servers of each request and hears how it ended.

Why not simpy or the YAFS core: with processor sharing every change in a server's occupancy
moves the finishing time of every job on it. Here each server keeps a *virtual time* (the
service one job has received since the start, which grows at ``speed[n]``); a job finishes when
the virtual time reaches its start value plus its work, so an occupancy change costs one heap
push instead of one reschedule per running job, and stale events are skipped by a version
number. That keeps 10^6 requests within a minute of pure Python (``benchmarks/bench_multiuser.py``).

Units: seconds; work is in seconds of service at speed 1 (one job alone on a reference server).
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np

from yafs_safetail.contention.types import (
    DISPATCH_MODES,
    Dispatcher,
    EngineError,
    EngineResult,
    EngineSettings,
    RequestBlock,
    RequestOutcome,
    ServerSpec,
)

__all__ = ["DISPATCH_MODES", "Dispatcher", "EngineError", "EngineResult", "EngineSettings",
           "RequestBlock", "RequestOutcome", "ServerSpec", "run_engine"]

# Copy record fields (a copy is a small list, dropped once settled). _LINK is the link the copy
# is transferring on (2 * server for its input, 2 * server + 1 for its output) or -1; _LEFT is
# the fraction of that transfer left at _LSINCE, _LDUR the whole transfer's time at the link's
# current level, _LVER its completion event's version, _LTABLE its time per level, _LSTART when
# it began.
(_REQ, _SERVER, _STATE, _WORK, _RTT, _OUT, _IN, _ARRIVE, _START, _END,
 _LINK, _LEFT, _LSINCE, _LDUR, _LVER, _LTABLE, _LSTART) = range(17)
# Copy states.
_TRANSIT, _QUEUED, _RUNNING, _REPLYING, _DONE, _CANCELLED, _REFUSED = range(7)
# Request record fields.
_R_INDEX, _R_EMIT, _R_COPIES, _R_DONE, _R_REFUSED, _R_PENDING, _R_TIED = range(7)
# Event kinds.
_AT_SERVER, _SERVER_DONE, _REPLY, _CANCEL, _HEDGE, _BACKGROUND, _LINK_DONE = range(7)


def run_engine(
    settings: EngineSettings,
    emit_s: Sequence[float],
    block_size: int,
    block: Callable[[int], RequestBlock],
    dispatcher: Dispatcher,
) -> EngineResult:
    """Simulate every request until all copies have settled.

    Args:
        settings: servers and options.
        emit_s: emission times, non-decreasing.
        block_size: requests per block.
        block: ``block(k)`` returns requests ``k * block_size ..``; asked once per block, in order,
            and dropped once every request of the block has been dispatched.
        dispatcher: the method.
    """
    if dispatcher.mode not in DISPATCH_MODES:
        raise EngineError(f"dispatch mode {dispatcher.mode!r}: expected one of {', '.join(DISPATCH_MODES)}")
    n_requests = len(emit_s)
    n_servers = len(settings.servers)
    levels = settings.contention_levels
    top_level = levels - 1
    queue_mode = settings.queue
    cancel_mode = settings.cancel
    shared_links = settings.shared_links
    fallback_s = settings.fallback_latency_s
    hedge_mode = dispatcher.mode == "hedge"
    tied_mode = dispatcher.mode == "tied"
    wants = dispatcher.wants_outcomes
    choose = dispatcher.choose
    completed = dispatcher.completed

    slots = [s.slots for s in settings.servers]
    speed = [s.speed for s in settings.servers]
    own = [0] * n_servers        # our copies running
    waiting = [0] * n_servers    # our copies queued (not cancelled)
    background = [0] * n_servers
    vtime = [0.0] * n_servers    # service one job has received since the start
    vlast = [0.0] * n_servers    # when vtime was last brought up to date
    version = [0] * n_servers
    jobs: list[list[tuple[float, int, list]]] = [[] for _ in range(n_servers)]
    queues: list[deque[list]] = [deque() for _ in range(n_servers)]
    links: list[list[list]] = [[] for _ in range(2 * n_servers)]  # copies transferring per link

    latency = np.full(n_requests, np.nan)
    n_copies = np.zeros(n_requests, dtype=np.int64)
    refused = np.zeros(n_requests, dtype=np.int64)
    fallback = np.zeros(n_requests, dtype=bool)
    winner = np.full(n_requests, -1, dtype=np.int64)
    emit = np.asarray(emit_s, dtype=float)
    if n_requests and np.any(np.diff(emit) < 0):
        raise EngineError("emission times must be non-decreasing")
    result = EngineResult(emit, latency, n_copies, refused, fallback, winner)

    events: list[tuple] = []
    push = heapq.heappush
    pop = heapq.heappop
    seq = 0
    now = 0.0
    busy_s = 0.0
    cancelled_copies = 0

    bg_rows = settings.background
    period_s = settings.background_period_s
    if bg_rows:
        for i in range(n_servers):
            background[i] = bg_rows[0][i]
        if math.isfinite(period_s):
            push(events, (period_s, seq, _BACKGROUND, 1, None))
            seq += 1

    def advance(i: int) -> None:
        if own[i]:
            vtime[i] += speed[i][own[i] + background[i]] * (now - vlast[i])
        vlast[i] = now

    def reschedule(i: int) -> None:
        nonlocal seq
        heap = jobs[i]
        while heap and heap[0][2][_STATE] != _RUNNING:
            pop(heap)
        version[i] += 1
        if heap:
            at = now + (heap[0][0] - vtime[i]) / speed[i][own[i] + background[i]]
            push(events, (at if at > now else now, seq, _SERVER_DONE, i, version[i]))
            seq += 1

    def start(i: int, copy: list) -> None:
        # The caller has advanced server i to now and reschedules it afterwards.
        nonlocal seq
        nonlocal cancelled_copies
        own[i] += 1
        copy[_STATE] = _RUNNING
        copy[_START] = now
        push(jobs[i], (vtime[i] + copy[_WORK], seq, copy))
        seq += 1
        if tied_mode and not copy[_REQ][_R_TIED]:
            # Only the first copy to start cancels its siblings; a sibling that starts before
            # the cancellation reaches it runs until it does (both cancelling would lose both).
            copy[_REQ][_R_TIED] = True
            for other in copy[_REQ][_R_COPIES]:
                if other is not copy and other[_STATE] <= _RUNNING:
                    send_cancel(other)

    def fill_from_queue(i: int) -> None:
        queue = queues[i]
        while queue and own[i] + background[i] < slots[i]:
            copy = queue.popleft()
            if copy[_STATE] == _QUEUED:
                waiting[i] -= 1
                start(i, copy)

    def occupancy_changed(i: int) -> None:
        # Occupancy changed (server advanced to now): waiting copies may start, and the next
        # completion moves.
        if queue_mode:
            fill_from_queue(i)
        reschedule(i)

    def link_changed(link: int) -> None:
        # The link's number of transfers (or its server's background) changed: bring every
        # transfer on it up to now at its old pace and reschedule its end at the new level.
        nonlocal seq
        active = links[link]
        level = background[link >> 1] + len(active) - 1
        if level > top_level:
            level = top_level
        for copy in active:
            whole_s = copy[_LDUR]
            if whole_s > 0.0:
                copy[_LEFT] -= (now - copy[_LSINCE]) / whole_s
            copy[_LSINCE] = now
            whole_s = 2.0 * copy[_LTABLE][level]
            copy[_LDUR] = whole_s
            copy[_LVER] += 1
            left = copy[_LEFT]
            push(events, (now + left * whole_s if left > 0.0 else now, seq, _LINK_DONE, copy, copy[_LVER]))
            seq += 1

    def start_transfer(copy: list, link: int, by_level: Sequence[float]) -> None:
        copy[_LINK] = link
        copy[_LEFT] = 1.0
        copy[_LSINCE] = now
        copy[_LDUR] = 0.0
        copy[_LTABLE] = by_level
        copy[_LSTART] = now
        links[link].append(copy)
        link_changed(link)

    def leave_link(copy: list) -> None:
        link = copy[_LINK]
        links[link].remove(copy)
        copy[_LINK] = -1
        if links[link]:
            link_changed(link)

    def send_cancel(copy: list) -> None:
        nonlocal seq
        push(events, (now + copy[_RTT], seq, _CANCEL, copy, None))
        seq += 1

    def finish(req: list, outcome_latency: float, copy: list | None) -> None:
        j = req[_R_INDEX]
        req[_R_DONE] = True
        latency[j] = outcome_latency
        refused[j] = req[_R_REFUSED]
        if copy is None:
            fallback[j] = True
        else:
            winner[j] = copy[_SERVER]
        if wants:
            sent = tuple(c[_SERVER] for c in req[_R_COPIES])
            if copy is None:
                outcome = RequestOutcome(j, req[_R_EMIT], outcome_latency, sent, req[_R_REFUSED], True, -1,
                                         math.nan, math.nan, math.nan, math.nan)
            else:
                outcome = RequestOutcome(j, req[_R_EMIT], outcome_latency, sent, req[_R_REFUSED], False,
                                         copy[_SERVER], copy[_IN], copy[_OUT][0], copy[_RTT],
                                         copy[_END] - copy[_ARRIVE])
            completed(outcome)

    def send(req: list, i: int, tables: RequestBlock, r: int) -> None:
        nonlocal seq
        base = i * levels
        rtt = tables.propagation_s[r][i]
        # The output's transfer term is read when the copy finishes computing.
        out_by_level = tables.output_transfer_s[r][base:base + levels]
        copy = [req, i, _TRANSIT, tables.work_s[r][i], rtt, out_by_level, 0.0, 0.0, 0.0, 0.0,
                -1, 0.0, 0.0, 0.0, 0, None, 0.0]
        req[_R_COPIES].append(copy)
        n_copies[req[_R_INDEX]] += 1
        if shared_links:
            in_by_level = tables.input_transfer_s[r][base:base + levels]
            if any(in_by_level):
                start_transfer(copy, 2 * i, in_by_level)
                return
            in_s = 0.0  # nothing to send: the link is not used
        else:
            others = own[i] + waiting[i] + background[i]
            in_s = tables.input_transfer_s[r][base + (others if others < top_level else top_level)]
            copy[_IN] = in_s
        push(events, (now + 2.0 * in_s + rtt, seq, _AT_SERVER, copy, None))
        seq += 1

    def hedge_next(req: list) -> None:
        pending = req[_R_PENDING]
        if pending:
            server, tables, r = pending.pop(0)
            send(req, server, tables, r)

    block_index = -1
    tables: RequestBlock | None = None
    next_request = 0
    next_emit = float(emit[0]) if n_requests else math.inf
    emit_list = emit.tolist()
    while True:
        if next_request < n_requests and next_emit <= (events[0][0] if events else math.inf):
            # A request is emitted.
            now = next_emit
            j = next_request
            next_request += 1
            next_emit = emit_list[next_request] if next_request < n_requests else math.inf
            if j // block_size != block_index:
                block_index = j // block_size
                tables = block(block_index)
            assert tables is not None
            r = j - tables.first
            active = [own[i] + waiting[i] + background[i] for i in range(n_servers)]
            chosen = list(choose(j, active))
            req: list = [j, now, [], False, 0, None, 0]
            if hedge_mode:
                send(req, chosen[0], tables, r)
                if len(chosen) > 1:
                    req[_R_PENDING] = [(server, tables, r) for server in chosen[1:]]
                    delay_s = dispatcher.hedge_delay_s()
                    # No timer for an infinite delay (the next copy then goes only if the first
                    # is refused): an event at infinity would poison the servers' clocks.
                    if delay_s < math.inf:
                        push(events, (now + delay_s, seq, _HEDGE, req, None))
                        seq += 1
            else:
                for server in chosen:
                    send(req, server, tables, r)
            continue
        if not events:
            break
        now, _, kind, a, b = pop(events)
        if kind == _SERVER_DONE:
            i = a
            if b != version[i]:
                continue
            advance(i)
            heap = jobs[i]
            limit = vtime[i] + 1e-9 * (1.0 + abs(vtime[i]))
            while heap and (heap[0][2][_STATE] != _RUNNING or heap[0][0] <= limit):
                _, _, copy = pop(heap)
                if copy[_STATE] != _RUNNING:
                    continue
                own[i] -= 1
                busy_s += now - copy[_START]
                copy[_STATE] = _REPLYING
                copy[_END] = now
                if shared_links:
                    out_by_level = copy[_OUT]
                    if any(out_by_level):
                        start_transfer(copy, 2 * i + 1, out_by_level)
                        continue
                    out_s = 0.0
                else:
                    others = own[i] + waiting[i] + background[i]
                    level = others if others < top_level else top_level
                    out_s = copy[_OUT][level]
                copy[_OUT] = (out_s,)
                push(events, (now + 2.0 * out_s + copy[_RTT], seq, _REPLY, copy, None))
                seq += 1
            occupancy_changed(i)
        elif kind == _AT_SERVER:
            copy = a
            if copy[_STATE] == _CANCELLED:
                continue
            i = copy[_SERVER]
            copy[_ARRIVE] = now
            if own[i] + background[i] < slots[i] and not (queue_mode and waiting[i]):
                advance(i)
                start(i, copy)
                reschedule(i)
            elif queue_mode:
                copy[_STATE] = _QUEUED
                waiting[i] += 1
                queues[i].append(copy)
            else:
                copy[_STATE] = _REFUSED
                req = copy[_REQ]
                req[_R_REFUSED] += 1
                if not req[_R_DONE]:
                    if hedge_mode and req[_R_PENDING]:
                        hedge_next(req)
                    elif all(c[_STATE] == _REFUSED for c in req[_R_COPIES]) and not req[_R_PENDING]:
                        finish(req, fallback_s, None)
        elif kind == _REPLY:
            copy = a
            copy[_STATE] = _DONE
            req = copy[_REQ]
            if req[_R_DONE]:
                continue
            finish(req, now - req[_R_EMIT], copy)
            req[_R_PENDING] = None
            if cancel_mode:
                for other in req[_R_COPIES]:
                    # (A reply still on its up link is cancelled too; _LINK is -1 otherwise.)
                    if other[_STATE] <= _RUNNING or other[_LINK] >= 0:
                        send_cancel(other)
        elif kind == _CANCEL:
            copy = a
            state = copy[_STATE]
            if state == _TRANSIT or (state == _REPLYING and copy[_LINK] >= 0):
                # Still being sent (its input, or its reply on the up link): the transfer stops.
                if copy[_LINK] >= 0:
                    leave_link(copy)
                copy[_STATE] = _CANCELLED
                cancelled_copies += 1
            elif state == _QUEUED:
                copy[_STATE] = _CANCELLED
                waiting[copy[_SERVER]] -= 1
                cancelled_copies += 1
            elif state == _RUNNING:
                i = copy[_SERVER]
                advance(i)
                copy[_STATE] = _CANCELLED
                own[i] -= 1
                busy_s += now - copy[_START]
                cancelled_copies += 1
                occupancy_changed(i)
        elif kind == _LINK_DONE:
            copy = a
            if b != copy[_LVER] or copy[_LINK] < 0:
                continue
            link = copy[_LINK]
            term_s = 0.5 * (now - copy[_LSTART])  # one of Eq. 1's two equal transfer terms
            leave_link(copy)
            if link & 1:
                copy[_OUT] = (term_s,)
                push(events, (now + copy[_RTT], seq, _REPLY, copy, None))
            else:
                copy[_IN] = term_s
                push(events, (now + copy[_RTT], seq, _AT_SERVER, copy, None))
            seq += 1
        elif kind == _HEDGE:
            req = a
            if not req[_R_DONE]:
                hedge_next(req)
        else:  # _BACKGROUND
            row = bg_rows[a % len(bg_rows)]
            for i in range(n_servers):
                if row[i] != background[i]:
                    advance(i)
                    background[i] = row[i]
                    occupancy_changed(i)
                    if shared_links:
                        for link in (2 * i, 2 * i + 1):
                            if links[link]:
                                link_changed(link)
            # Background changes only matter while requests remain.
            if next_request < n_requests or events:
                push(events, (now + period_s, seq, _BACKGROUND, a + 1, None))
                seq += 1
    result.busy_s = busy_s
    result.cancelled_copies = cancelled_copies
    result.end_s = now
    return result
