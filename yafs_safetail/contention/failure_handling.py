"""The contention loop's failures, time-outs and energy (a part of
:class:`~yafs_safetail.contention.simulation.Simulation`, kept apart to be read on its own).

An outage loses every copy of ours on the server or its links; a request without a reply by
its time-out ends with the on-device fallback; each copy's server time is charged at the
server's marginal power, each transfer at the device's radio power (docs/failures_energy.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from yafs_safetail.contention.state import LOST, QUEUED, REFUSED, REPLYING, RUNNING, TRANSIT
from yafs_safetail.contention.types import END_ALL_LOST_CODE, END_TIMEOUT_CODE

if TYPE_CHECKING:
    from yafs_safetail.contention.state import Copy, Request, Server, Transfer
    from yafs_safetail.contention.types import EngineSettings


class FailureHandling:
    """Failures, time-outs and energy: methods of the contention loop (mixed into Simulation)."""

    if TYPE_CHECKING:  # the loop's state these methods use (Simulation sets it)
        settings: EngineSettings
        servers: list[Server]
        lost: list[int]
        now_s: float
        busy_s: float
        shared_links: bool
        timeout_s: float
        per_process_w: float
        radio_up_j_per_byte: float
        radio_down_j_per_byte: float
        radio_active_w: float
        lost_copies: int
        server_energy_j: list[float]
        radio_energy_j: list[float]
        saved_energy_j: list[float]

        def schedule(self, at_s: float, handler: Callable[[Any, int], None], subject: Any,
                     version: int = 0) -> None: ...
        def finish(self, request: Request, latency_s: float, copy: Copy | None, reason: int = 0) -> None: ...
        def cancel_others(self, request: Request) -> None: ...
        def reschedule(self, server: Server) -> None: ...

    def lose(self, copy: Copy) -> None:
        """``copy`` is lost to its server's failure (nobody is told)."""
        copy.state = LOST
        request = copy.request
        request.lost += 1
        self.lost[request.index] += 1
        self.lost_copies += 1

    def lost_on_the_way(self, copy: Copy) -> bool:
        """Whether ``copy``, not on a link now, was lost by a failure it has not met yet: its
        server went down after it left the user (its input on the way), or, with at-start
        links, before its reply had left the server. (Always False on a server that never went
        down: ``on_reply`` and ``on_cancel`` check ``down_starts_s`` first, so without failures
        a copy costs no call here.)"""
        state = copy.state
        if state == TRANSIT and copy.transfer is None:
            return copy.server.went_down_within(copy.sent_s, self.now_s)
        if state == REPLYING and not self.shared_links:
            return copy.server.went_down_within(copy.end_s, min(self.now_s, copy.reply_left_s))
        return False

    def charge_upload(self, request: Request, fraction: float, transfer_s: float) -> None:
        """The device sent ``fraction`` of the request's input over ``transfer_s``."""
        self.radio_energy_j[request.index] += (self.radio_up_j_per_byte * fraction * request.input_bytes
                                               + self.radio_active_w * transfer_s)

    def charge_download(self, request: Request, fraction: float, transfer_s: float) -> None:
        """The device received ``fraction`` of a reply over ``transfer_s``."""
        self.radio_energy_j[request.index] += (self.radio_down_j_per_byte * fraction * request.output_bytes
                                               + self.radio_active_w * transfer_s)

    def charge_stopped(self, transfer: Transfer) -> None:
        """``transfer`` stops now (cancelled or lost): the device's radio for what it moved."""
        now_s = self.now_s
        charge = self.charge_download if transfer.link.is_up else self.charge_upload
        charge(transfer.copy.request, transfer.sent_fraction(now_s), now_s - transfer.started_s)

    def stop_computing(self, copy: Copy) -> None:
        """``copy`` stops running now (done, cancelled or lost): its server time and energy."""
        ran_s = self.now_s - copy.start_s
        self.busy_s += ran_s
        self.server_energy_j[copy.request.index] += self.per_process_w * ran_s

    def energy_so_far(self, request: Request) -> tuple[float, float, float]:
        """The request's servers', radio and saved energy until now (running copies included)."""
        j = request.index
        running_s = sum(self.now_s - c.start_s for c in request.copies if c.state == RUNNING)
        return (self.server_energy_j[j] + self.per_process_w * running_s, self.radio_energy_j[j],
                self.saved_energy_j[j])

    def schedule_outages(self) -> None:
        for server, intervals in zip(self.servers, self.settings.outages, strict=False):
            for down_s, up_s in intervals:
                self.schedule(down_s, self.on_server_down, server)
                if up_s < math.inf:
                    self.schedule(up_s, self.on_server_up, server)

    def on_timeout(self, request: Request, _: int) -> None:
        """No reply within the time-out: the on-device fallback, after it."""
        if request.done:
            return
        any_lost, all_lost = False, True
        for copy in request.copies:
            if copy.state == REFUSED:
                continue
            if copy.state != LOST and self.lost_on_the_way(copy):
                self.lose(copy)
            if copy.state == LOST:
                any_lost = True
            else:
                all_lost = False
        reason = END_ALL_LOST_CODE if any_lost and all_lost else END_TIMEOUT_CODE
        self.finish(request, self.timeout_s + self.settings.fallback_latency_s, None, reason)
        request.unsent = None
        if self.settings.cancel:
            self.cancel_others(request)

    def on_server_down(self, server: Server, _version: int) -> None:
        """``server`` fails: every copy on it or on its links is lost, its slots and links free."""
        now_s = self.now_s
        server.advance(now_s)
        server.is_down = True
        server.down_starts_s.append(now_s)
        for *_, copy in server.jobs:
            if copy.state == RUNNING:
                server.own -= 1
                self.stop_computing(copy)
                self.lose(copy)
        server.jobs.clear()
        for copy in server.queue:
            if copy.state == QUEUED:
                server.waiting -= 1
                self.lose(copy)
        server.queue.clear()
        for link in (server.down, server.up):
            for transfer in link.transfers:
                self.charge_stopped(transfer)
                copy = transfer.copy
                copy.transfer = None
                self.lose(copy)
            link.transfers.clear()
        self.reschedule(server)  # nothing runs: its pending completion goes stale

    def on_server_up(self, server: Server, _: int) -> None:
        """``server`` is repaired: it serves the copies that reach it from now on."""
        server.is_down = False
