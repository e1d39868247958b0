"""The contention loop's shared capacity: transfers sharing a server's links and the load
trace's background tenants (a part of
:class:`~yafs_safetail.contention.simulation.Simulation`, kept apart to be read on its own).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

from yafs_safetail.contention.state import Transfer

_push = heapq.heappush

if TYPE_CHECKING:
    from yafs_safetail.contention.state import Copy, Link, Server
    from yafs_safetail.contention.types import EngineSettings


class SharedCapacity:
    """Links and background tenants: methods of the contention loop (mixed into Simulation)."""

    if TYPE_CHECKING:  # the loop's state these methods use (Simulation sets it)
        settings: EngineSettings
        servers: list[Server]
        now_s: float
        top_level: int
        sequence: Iterator[int]
        shared_links: bool
        next_request: int
        n_requests: int
        events: list[Any]

        def schedule(self, at_s: float, handler: Callable[[Any, int], None], subject: Any,
                     version: int = 0) -> None: ...
        def level_of(self, users: int) -> int: ...
        def occupancy_changed(self, server: Server) -> None: ...
        def charge_upload(self, request: Any, fraction: float, transfer_s: float) -> None: ...
        def charge_download(self, request: Any, fraction: float, transfer_s: float) -> None: ...
        def on_reply(self, copy: Copy, _: int) -> None: ...
        def on_arrival(self, copy: Copy, _: int) -> None: ...

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
        users = link.server.background + len(link.transfers) - 1
        level = users if users < self.top_level else self.top_level  # (level_of)
        # The engine's most frequent step, written out without calls (each would cost about
        # as much as the arithmetic): schedule's push, the events' end times.
        events, sequence, on_transfer_end = self.events, self.sequence, self.on_transfer_end
        for transfer in link.transfers:
            whole_s = transfer.whole_s
            if whole_s > 0.0:  # what it sent since ``since_s``, at its old pace
                transfer.left -= (now_s - transfer.since_s) / whole_s
            transfer.since_s = now_s
            whole_s = 2.0 * transfer.time_by_level_s[level]
            transfer.whole_s = whole_s
            transfer.version += 1  # its earlier end events go stale
            left = transfer.left
            end_s = now_s + left * whole_s if left > 0.0 else now_s
            _push(events, (end_s, next(sequence), on_transfer_end, transfer, transfer.version))

    def start_background(self) -> None:
        rows = self.settings.background
        if not rows:
            return
        for server in self.servers:
            server.background = rows[0][server.index]
        if math.isfinite(self.settings.background_period_s):
            self.schedule(self.settings.background_period_s, self.on_background_change, 1)

    def on_transfer_end(self, transfer: Transfer, version: int) -> None:
        """``transfer`` has sent everything (unless a later change moved its end)."""
        copy = transfer.copy
        if version != transfer.version or copy.transfer is not transfer:
            return
        transfer_s = self.now_s - transfer.started_s
        term_s = 0.5 * transfer_s  # one of Eq. 1's two equal transfer terms
        self.leave_link(transfer)
        if transfer.link.is_up:
            copy.output_s = term_s
            self.charge_download(copy.request, 1.0, transfer_s)
            handler = self.on_reply
        else:
            copy.input_s = term_s
            self.charge_upload(copy.request, 1.0, transfer_s)
            handler = self.on_arrival
        # (schedule, inlined: see Simulation.schedule.)
        _push(self.events, (self.now_s + copy.propagation_s, next(self.sequence), handler, copy, 0))

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
