"""What the contention engine's event loop moves around: servers, their links, requests, their
copies and the copies' transfers (``contention.engine`` drives them).

Plain objects with slots, compared by identity: the loop reads and writes their fields millions
of times per run, and a slot is as fast to read as a list entry.
"""

from __future__ import annotations

import heapq
import math
from bisect import bisect_left
from collections import deque
from dataclasses import dataclass, field

from yafs_safetail.contention.types import FirstReply, RequestBlock

# A copy's states, in the order a copy moves through them; everything up to RUNNING can still
# hold or take a slot, so ``state <= RUNNING`` reads "not past computing".
TRANSIT = 0    # on its way to the server (its input on the down link, then ρ)
QUEUED = 1     # waiting in the server's FIFO queue
RUNNING = 2    # holding a slot, computing
REPLYING = 3   # its reply on the up link, then ρ back
DONE = 4       # its reply arrived
CANCELLED = 5  # stopped by a cancel message (or never started)
REFUSED = 6    # the server was full
LOST = 7       # its server was down when it got there, or went down before its reply left


@dataclass(slots=True, eq=False)
class Link:
    """One direction of a server's network: ``is_up`` for replies, else inputs.

    Attributes:
        server: the server it belongs to (its background tenants share the link too).
        is_up: True for the up link (replies), False for the down link (inputs).
        transfers: the transfers on it now, in the order they joined.
    """

    server: Server
    is_up: bool
    transfers: list[Transfer] = field(default_factory=list)


@dataclass(slots=True, eq=False)
class Server:
    """One edge server, processor-shared between the jobs running on it.

    Attributes:
        index: its position in the settings (and in a policy's choice).
        slots: jobs that can run at once (ours and background tenants).
        speed: per-job progress rate for each number of running jobs.
        own: our copies running.
        waiting: our copies in the queue (not cancelled).
        background: background tenants now.
        virtual_s: the service one job has received since the start (grows at ``speed[n]``).
        virtual_at_s: when ``virtual_s`` was last brought up to date.
        version: the number of its latest completion event (older ones are stale).
        jobs: heap of (virtual time at which the job ends, sequence, copy).
        queue: copies waiting for a slot, first come first served.
        down: the link that carries inputs to it.
        up: the link that carries its replies.
        active_s: ∫ own dt since the start (our copies computing), kept apart from the copies
            so that their energy can be checked against it.
        is_down: the server has failed and not come back yet.
        down_starts_s: when it went down, in order (copies in flight check them).
    """

    index: int
    slots: int
    speed: tuple[float, ...]
    own: int = 0
    waiting: int = 0
    background: int = 0
    virtual_s: float = 0.0
    virtual_at_s: float = 0.0
    version: int = 0
    jobs: list[tuple[float, int, Copy]] = field(default_factory=list)
    queue: deque[Copy] = field(default_factory=deque)
    down: Link = field(init=False)
    up: Link = field(init=False)
    active_s: float = 0.0
    is_down: bool = False
    down_starts_s: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.down = Link(self, False)
        self.up = Link(self, True)

    def active_users(self) -> int:
        """Ours running or waiting plus the background tenants (ℓ_i as a policy sees it)."""
        return self.own + self.waiting + self.background

    def advance(self, now_s: float) -> None:
        """Bring the virtual time (and ∫ own dt) up to ``now_s`` at the current occupancy."""
        own = self.own
        if own:
            elapsed_s = now_s - self.virtual_at_s
            self.virtual_s += self.speed[own + self.background] * elapsed_s
            self.active_s += own * elapsed_s
        self.virtual_at_s = now_s

    def went_down_within(self, start_s: float, end_s: float) -> bool:
        """Whether it went down at some time in ``[start_s, end_s]``."""
        starts = self.down_starts_s
        if not starts or starts[-1] < start_s:
            return False
        index = bisect_left(starts, start_s)
        return index < len(starts) and starts[index] <= end_s

    def next_end_s(self, now_s: float) -> float | None:
        """When its first running job ends at the current speed (None: nothing runs); stale
        jobs (cancelled) are dropped and the version moves on, so earlier end events go stale."""
        jobs = self.jobs
        while jobs and jobs[0][2].state != RUNNING:
            heapq.heappop(jobs)
        self.version += 1
        if not jobs:
            return None
        end_s = now_s + (jobs[0][0] - self.virtual_s) / self.speed[self.own + self.background]
        return end_s if end_s > now_s else now_s


@dataclass(slots=True, eq=False)
class Request:
    """A request from its emission until its first reply (or fallback).

    Attributes:
        index: its position in emission order.
        emit_s: when it was emitted.
        copies: the copies sent so far, in sending order.
        done: its first reply arrived, or every copy was refused.
        refused: copies refused so far.
        unsent: hedge only: the (server, block, row) of copies not sent yet, or None.
        tied: tied only: one of its copies has started running.
        input_bytes: what each copy uploads from the device.
        output_bytes: what each reply brings down to it.
        lost: copies lost so far.
    """

    index: int
    emit_s: float
    copies: list[Copy] = field(default_factory=list)
    done: bool = False
    refused: int = 0
    unsent: list[tuple[int, RequestBlock, int]] | None = None
    tied: bool = False
    input_bytes: float = 0.0
    output_bytes: float = 0.0
    lost: int = 0


@dataclass(slots=True, eq=False)
class Copy:
    """One copy of a request, sent to one server.

    Attributes:
        request: the request it belongs to.
        server: where it goes.
        work_s: its service need (seconds at speed 1).
        propagation_s: ρ to its server, one way.
        output_by_level: its output transfer term per contention level.
        state: one of the module's copy states.
        input_s: its input transfer term as it happened (0 until known).
        output_s: its output transfer term as it happened (0 until known).
        arrive_s: when it reached the server.
        start_s: when it started running.
        end_s: when it finished running.
        transfer: the transfer it is in now (input or reply), or None.
        sent_s: when it left the user.
        finish_virtual_s: the server's virtual time at which its work is done (once running).
        reply_left_s: when its reply has left the server's up link (``links="at-start"``).
    """

    request: Request
    server: Server
    work_s: float
    propagation_s: float
    output_by_level: list[float]
    state: int = TRANSIT
    input_s: float = 0.0
    output_s: float = 0.0
    arrive_s: float = 0.0
    start_s: float = 0.0
    end_s: float = 0.0
    transfer: Transfer | None = None
    sent_s: float = 0.0
    finish_virtual_s: float = 0.0
    reply_left_s: float = 0.0


@dataclass(slots=True, eq=False)
class Transfer:
    """A copy's input or reply on a shared link, processor-shared with the others there
    (``SharedCapacity.link_changed`` brings it up to date and moves its end).

    Attributes:
        copy: whose data it carries.
        link: the link it is on.
        time_by_level_s: one of Eq. 1's two equal terms per contention level (the whole transfer
            takes twice that).
        started_s: when it joined the link.
        left: the fraction of it still to send at ``since_s``.
        since_s: when ``left`` was last brought up to date.
        whole_s: the whole transfer's time at the link's current level (0 before the first).
        version: the number of its latest end event (older ones are stale).
    """

    copy: Copy
    link: Link
    time_by_level_s: list[float]
    started_s: float
    left: float = 1.0
    since_s: float = 0.0
    whole_s: float = 0.0
    version: int = 0

    def sent_fraction(self, now_s: float) -> float:
        """The share of it sent by ``now_s`` (at its current pace), in [0, 1]."""
        left = self.left - (now_s - self.since_s) / self.whole_s if self.whole_s > 0.0 else self.left
        return min(1.0, max(0.0, 1.0 - left))


def first_reply(request: Request, latency_s: float, copy: Copy | None, end_reason: str,
                energy_j: tuple[float, float, float]) -> FirstReply:
    """How ``request`` ended: with ``copy``'s reply after ``latency_s``, or (None) the fallback,
    for ``end_reason``; ``energy_j``: its servers', radio and saved energy until now."""
    sent = tuple(c.server.index for c in request.copies)
    server_j, radio_j, saved_j = energy_j
    if copy is None:
        return FirstReply(request.index, request.emit_s, latency_s, sent, request.refused, True, -1,
                          math.nan, math.nan, math.nan, math.nan, end_reason, request.lost,
                          server_j, radio_j, saved_j)
    return FirstReply(request.index, request.emit_s, latency_s, sent, request.refused, False,
                      copy.server.index, copy.input_s, copy.output_s, copy.propagation_s,
                      copy.end_s - copy.arrive_s, end_reason, request.lost, server_j, radio_j, saved_j)
