"""What the contention engine takes and gives: servers, request blocks, the dispatcher it asks,
and per-request outcomes (``contention.engine`` runs them)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

#: The dispatch modes the engine runs (the contention world's declaration): copies all at once,
#: one then the next after a delay (hedged request), or all at once with the others cancelled
#: when one starts running (tied request).
DISPATCH_MODES: tuple[str, ...] = ("all", "hedge", "tied")


class Dispatcher(Protocol):
    """What the engine asks for each request and tells when it ends.

    Attributes:
        mode: one of :data:`DISPATCH_MODES`.
        wants_outcomes: False skips :meth:`completed` (saves a call per request).
    """

    mode: str
    wants_outcomes: bool

    def choose(self, request: int, active_users: list[int]) -> Sequence[int]:
        """The servers of request ``request`` (for ``"hedge"``: in the order to try them),
        given each server's active users (ours running or waiting, plus background tenants)."""
        ...

    def hedge_delay_s(self) -> float:
        """For ``"hedge"``: how long to wait for a reply before sending the next copy."""
        ...

    def completed(self, outcome: RequestOutcome) -> None:
        """Request ``outcome.request`` has its first reply (or fell back to the device)."""
        ...


@dataclass(frozen=True, slots=True)
class RequestOutcome:
    """How one request ended, at its first reply (or fallback): what the engine tells the
    dispatcher, which turns it into the policy's :class:`~yafs_safetail.record.RequestRecord`
    (the request outcome every world gives a policy).

    Not the core's ``yafs.outcomes.RequestOutcome``, though both describe a request and its first
    reply: the core's is built once every copy has settled (each copy's status, YAFS process and
    node; refusals counted over all copies) and holds no Eq. 1 parts, while this one comes at the
    first reply, when the policy's feedback is due, with the winning copy's Eq. 1 parts. Built
    from the core's type, it would have to wait for the slowest copy, which moves every
    learner's feedback and so changes results files.

    Attributes:
        request: its index (emission order).
        emit_s: when it was emitted.
        latency_s: first reply minus emission, or the fallback latency.
        servers: the servers copies were sent to, in sending order.
        refused: copies refused (server full) before the request ended.
        fallback: every copy was refused; the on-device version answered.
        winner: the server of the first reply (-1 for a fallback).
        input_transfer_s: the winning copy's one-way input transfer term, as it happened (half
            the time its input took, on a shared link at whatever levels it met; NaN for a
            fallback).
        output_transfer_s: its output transfer term, likewise.
        propagation_s: its one-way propagation ρ.
        server_s: from its arrival at the server to its end of service (waiting + computing).
    """

    request: int
    emit_s: float
    latency_s: float
    servers: tuple[int, ...]
    refused: int
    fallback: bool
    winner: int
    input_transfer_s: float
    output_transfer_s: float
    propagation_s: float
    server_s: float


@dataclass(frozen=True)
class ServerSpec:
    """One server.

    Attributes:
        slots: copies that can run at once (ours and background tenants); more are refused or
            wait in the FIFO queue.
        speed: per-job progress rate (work seconds per second) for 0, 1, 2, ... running jobs;
            long enough for every occupancy the run can reach (slots + largest background).
    """

    slots: int
    speed: tuple[float, ...]


@dataclass(frozen=True)
class RequestBlock:
    """Consecutive requests' per-server quantities, as plain lists (indexing a list is much
    faster than indexing an array with scalars).

    ``first`` is the index of the block's first request; entry ``[r]`` is request ``first + r``.
    Per (request, server, contention level) tables are flattened: ``[r][server * levels + level]``.

    Attributes:
        first: index of the first request.
        input_transfer_s: one of Eq. 1's two equal input transfer terms.
        output_transfer_s: one of Eq. 1's two equal output transfer terms.
        propagation_s: ρ per [r][server], one way.
        work_s: the copy's service need per [r][server] (seconds at speed 1).
    """

    first: int
    input_transfer_s: list[list[float]]
    output_transfer_s: list[list[float]]
    propagation_s: list[list[float]]
    work_s: list[list[float]]


@dataclass(frozen=True)
class EngineSettings:
    """How the servers behave towards copies.

    Attributes:
        servers: one spec per server.
        contention_levels: L, the number of bandwidth levels in the request tables.
        shared_links: True: a transfer is processor-shared over its duration, at level
            min(background tenants + other transfers on the same link, L - 1) as that changes;
            False: it takes its time at level min(other active users at the server, L - 1) when
            it starts (the single-user world's reading).
        queue: a FIFO waiting queue instead of refusal when the slots are full.
        cancel: cancel a request's other copies when its first reply arrives (the cancel
            message takes the server's one-way propagation ρ to get there).
        fallback_latency_s: a request whose copies were all refused ends with this latency.
        background_period_s: background tenants change every this many seconds.
        background: tenants per [period][server]; period p uses row p mod len (may be empty).
    """

    servers: tuple[ServerSpec, ...]
    contention_levels: int
    queue: bool
    cancel: bool
    fallback_latency_s: float
    shared_links: bool = True
    background_period_s: float = math.inf
    background: tuple[tuple[int, ...], ...] = ()


@dataclass
class EngineResult:
    """Per-request results in emission order (arrays of length n_requests).

    Attributes:
        emit_s, latency_s, n_copies, refused, fallback, winner: as in :class:`RequestOutcome`.
        busy_s: total server time copies spent running, over the run (work that counted or not).
        cancelled_copies: copies cancelled before they finished (computing, or sending their
            reply on a shared up link).
        end_s: simulated time when the last event was processed.
    """

    emit_s: np.ndarray
    latency_s: np.ndarray
    n_copies: np.ndarray
    refused: np.ndarray
    fallback: np.ndarray
    winner: np.ndarray
    busy_s: float = 0.0
    cancelled_copies: int = 0
    end_s: float = 0.0


class EngineError(ValueError):
    """A dispatcher or setting the engine cannot run (one line)."""
