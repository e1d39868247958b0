"""What the contention engine takes and gives: servers, request blocks, the dispatcher it asks,
each request's first reply (:class:`FirstReply`) and the run's results (``contention.engine``
runs them)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from yafs_safetail.edge.failures import (
    END_ALL_LOST,
    END_ALL_REFUSED,
    END_REASONS,
    END_REPLY,
    END_TIMEOUT,
)

#: Why a request ended, as the engine stores it (an index into ``END_REASONS``).
END_REPLY_CODE = END_REASONS.index(END_REPLY)
END_ALL_REFUSED_CODE = END_REASONS.index(END_ALL_REFUSED)
END_ALL_LOST_CODE = END_REASONS.index(END_ALL_LOST)
END_TIMEOUT_CODE = END_REASONS.index(END_TIMEOUT)

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

    def completed(self, reply: FirstReply) -> None:
        """Request ``reply.request`` has its first reply (or fell back to the device)."""
        ...


@dataclass(frozen=True, slots=True)
class FirstReply:
    """How one request ended, at its first reply (or fallback): what the engine tells the
    dispatcher (:meth:`Dispatcher.completed`), which turns it into the policy's
    :class:`~yafs_safetail.record.RequestRecord` (the request record every world gives a policy).

    Not the core's ``yafs.outcomes.RequestOutcome`` (hence a name of its own), though both
    describe a request and its first reply: the core's is built once every copy has settled (each copy's status, YAFS process and
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
        fallback: no reply ended it (every copy refused, or none answered within the time-out);
            the on-device version answered.
        winner: the server of the first reply (-1 for a fallback).
        input_transfer_s: the winning copy's one-way input transfer term, as it happened (half
            the time its input took, on a shared link at whatever levels it met; NaN for a
            fallback).
        output_transfer_s: its output transfer term, likewise.
        propagation_s: its one-way propagation ρ.
        server_s: from its arrival at the server to its end of service (waiting + computing).
        end_reason: why it ended, one of ``edge.failures.END_REASONS``.
        lost: its copies lost to a failed server by the time it ended.
        server_energy_j: the servers' marginal energy its copies had spent when it ended
            (per-process power × each copy's time computing so far).
        radio_energy_j: the device's radio energy of its uploads and downloads until it ended.
        saved_energy_j: the server energy its cancelled copies had not spent, until it ended.

    The energies are what had been spent when the request ended, the moment its feedback is
    due; the engine's result arrays hold each request's totals once every copy has settled.
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
    end_reason: str = END_REPLY
    lost: int = 0
    server_energy_j: float = 0.0
    radio_energy_j: float = 0.0
    saved_energy_j: float = 0.0

    @property
    def energy_j(self) -> float:
        """The servers' and the device's radio energy together."""
        return self.server_energy_j + self.radio_energy_j


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
        input_bytes: the request's input size per [r] (what the device uploads per copy);
            empty: no radio energy is charged for the bytes.
        output_bytes: the reply's size per [r] (what the device downloads per reply); empty
            likewise.
    """

    first: int
    input_transfer_s: list[list[float]]
    output_transfer_s: list[list[float]]
    propagation_s: list[list[float]]
    work_s: list[list[float]]
    input_bytes: list[float] = field(default_factory=list)
    output_bytes: list[float] = field(default_factory=list)


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
        outages: per server, its ``(down_s, up_s)`` intervals, sorted and disjoint (empty: no
            server ever fails). A copy on a server when it goes down (waiting, computing, its
            input or its reply on the server's links, its input on the way) is lost; a copy
            sent to a down server is lost at once. Nobody is told.
        timeout_s: a request without a reply this long after its emission ends with the
            fallback (latency: the time-out plus ``fallback_latency_s``); ``inf``: never.
        per_process_w: a server's marginal power per copy computing (server energy).
        radio_up_j_per_byte: the device's radio energy per byte uploaded (besides its
            ``radio_active_w`` over the transfer's time).
        radio_down_j_per_byte: likewise per byte downloaded.
        radio_active_w: the device's radio power while any transfer of its is on the air.
    """

    servers: tuple[ServerSpec, ...]
    contention_levels: int
    queue: bool
    cancel: bool
    fallback_latency_s: float
    shared_links: bool = True
    background_period_s: float = math.inf
    background: tuple[tuple[int, ...], ...] = ()
    outages: tuple[tuple[tuple[float, float], ...], ...] = ()
    timeout_s: float = math.inf
    per_process_w: float = 0.0
    radio_up_j_per_byte: float = 0.0
    radio_down_j_per_byte: float = 0.0
    radio_active_w: float = 0.0


@dataclass
class EngineResult:
    """Per-request results in emission order (arrays of length n_requests).

    Attributes:
        emit_s, latency_s, n_copies, refused, fallback, winner: as in :class:`FirstReply`.
        busy_s: total server time copies spent running, over the run (work that counted or not).
        cancelled_copies: copies cancelled before they finished (computing, or sending their
            reply on a shared up link).
        end_s: simulated time when the last event was processed.
        end_reason: per request, why it ended (an index into ``edge.failures.END_REASONS``).
        lost: per request, its copies lost to failed servers (all of them, after it ended too).
        server_energy_j: per request, per-process power × the time each of its copies computed.
        radio_energy_j: per request, the device's radio energy of every upload and download.
        saved_energy_j: per request, the server energy its cancelled copies did not spend.
        server_active_s: per server, ∫ (our copies computing) dt, accumulated apart from the
            copies: × per-process power, the server's dynamic energy from our copies.
        lost_copies: copies lost over the run.
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
    end_reason: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))
    lost: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    server_energy_j: np.ndarray = field(default_factory=lambda: np.zeros(0))
    radio_energy_j: np.ndarray = field(default_factory=lambda: np.zeros(0))
    saved_energy_j: np.ndarray = field(default_factory=lambda: np.zeros(0))
    server_active_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lost_copies: int = 0

    @property
    def energy_j(self) -> np.ndarray:
        """Per request, the servers' and the device's radio energy together."""
        return self.server_energy_j + self.radio_energy_j


class EngineError(ValueError):
    """A dispatcher or setting the engine cannot run (one line)."""
