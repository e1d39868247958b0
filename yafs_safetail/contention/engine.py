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

``run_engine`` checks its inputs and runs a ``simulation.Simulation``: the event loop, one
handler per kind of event, over the small objects of ``state`` (servers and their links,
requests, copies, transfers).

Units: seconds; work is in seconds of service at speed 1 (one job alone on a reference server).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from yafs_safetail.contention.simulation import Simulation
from yafs_safetail.contention.types import (
    DISPATCH_MODES,
    Dispatcher,
    EngineError,
    EngineResult,
    EngineSettings,
    FirstReply,
    RequestBlock,
    ServerSpec,
)

__all__ = ["DISPATCH_MODES", "Dispatcher", "EngineError", "EngineResult", "EngineSettings",
           "FirstReply", "RequestBlock", "ServerSpec", "run_engine"]


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

    Raises:
        EngineError: an unknown dispatch mode, emission times out of order, or outages without
            a finite time-out (a request whose copies were all lost would never end).
    """
    if dispatcher.mode not in DISPATCH_MODES:
        raise EngineError(f"dispatch mode {dispatcher.mode!r}: expected one of {', '.join(DISPATCH_MODES)}")
    if any(settings.outages) and not settings.timeout_s < np.inf:
        raise EngineError("outages: servers fail but timeout_s is not finite (a request whose copies "
                          "were all lost would never end)")
    emit = np.asarray(emit_s, dtype=float)
    if emit.shape[0] and np.any(np.diff(emit) < 0):
        raise EngineError("emission times must be non-decreasing")
    return Simulation(settings, emit, block_size, block, dispatcher).run()
