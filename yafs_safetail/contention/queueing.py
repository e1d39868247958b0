"""The stripped configuration that queueing theory solves exactly, to validate the engine.

Exponential service of rate μ at every server, one slot and a FIFO queue per server, no network
delay, instantaneous cancellation, Poisson arrivals of total rate λ at k servers. Then (Gardner
et al., SIGMETRICS 2015; facts.md):

* random single dispatch splits the arrivals into k independent M/M/1 queues of rate λ/k:
  E[T] = 1 / (μ - λ/k);
* sending every request to all k servers, cancelling the others when one finishes, behaves as
  one M/M/1 queue of rate kμ: E[T] = 1 / (kμ - λ).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from yafs_safetail.contention.engine import (
    EngineResult,
    EngineSettings,
    FirstReply,
    RequestBlock,
    ServerSpec,
    run_engine,
)

#: The two dispatch rules the theory covers.
QUEUEING_CASES: tuple[str, ...] = ("random-single", "all-cancel")


def single_dispatch_mean_s(arrival_rate: float, service_rate: float, n_servers: int) -> float:
    """E[T] of k M/M/1 queues each fed λ/k."""
    return 1.0 / (service_rate - arrival_rate / n_servers)


def send_to_all_mean_s(arrival_rate: float, service_rate: float, n_servers: int) -> float:
    """E[T] of one M/M/1 queue of rate kμ."""
    return 1.0 / (n_servers * service_rate - arrival_rate)


def theory_mean_s(case: str, arrival_rate: float, service_rate: float, n_servers: int) -> float:
    if case == "random-single":
        return single_dispatch_mean_s(arrival_rate, service_rate, n_servers)
    return send_to_all_mean_s(arrival_rate, service_rate, n_servers)


class _RandomSingle:
    mode = "all"
    wants_outcomes = False

    def __init__(self, n_servers: int, rng: np.random.Generator, n_requests: int) -> None:
        # Drawn up front: one generator call instead of one per request.
        self._servers = rng.integers(n_servers, size=n_requests).tolist()

    def choose(self, request: int, active_users: list[int]) -> Sequence[int]:
        return (self._servers[request],)

    def hedge_delay_s(self) -> float:
        raise NotImplementedError

    def completed(self, reply: FirstReply) -> None:
        raise NotImplementedError


class _SendToAll:
    mode = "all"
    wants_outcomes = False

    def __init__(self, n_servers: int) -> None:
        self._all = tuple(range(n_servers))

    def choose(self, request: int, active_users: list[int]) -> Sequence[int]:
        return self._all

    def hedge_delay_s(self) -> float:
        raise NotImplementedError

    def completed(self, reply: FirstReply) -> None:
        raise NotImplementedError


@dataclass(frozen=True)
class QueueingRun:
    """One simulated case and its exact answer."""

    case: str
    n_requests: int
    utilisation: float
    simulated_mean_s: float
    theory_mean_s: float

    @property
    def rel_error(self) -> float:
        return abs(self.simulated_mean_s - self.theory_mean_s) / self.theory_mean_s


def simulate_case(case: str, n_servers: int, service_rate: float, utilisation: float,
                  n_requests: int, seed: int, warmup_fraction: float = 0.05) -> QueueingRun:
    """Simulate ``case`` at per-server utilisation ``utilisation`` (λ / kμ) and compare its mean
    response time (after a warm-up share of requests) with the exact one.

    Args:
        case: one of :data:`QUEUEING_CASES`.
        n_servers: k.
        service_rate: μ (1/s).
        utilisation: λ / (kμ), in (0, 1).
        n_requests: requests simulated.
        seed: the run's seed (arrivals, service times and dispatch each get their own stream).
        warmup_fraction: the first requests left out of the mean (the queues start empty).
    """
    if case not in QUEUEING_CASES:
        raise ValueError(f"case: {case!r} is not one of {', '.join(QUEUEING_CASES)}")
    if not 0 < utilisation < 1:
        raise ValueError(f"utilisation: {utilisation} must be in (0, 1) for a stable queue")
    arrival_rate = utilisation * n_servers * service_rate
    arrivals_seq, work_seq, dispatch_seq = np.random.SeedSequence([seed, QUEUEING_CASES.index(case)]).spawn(3)
    emit_s = np.cumsum(np.random.default_rng(arrivals_seq).exponential(1.0 / arrival_rate, n_requests))
    work_s = np.random.default_rng(work_seq).exponential(1.0 / service_rate, (n_requests, n_servers))
    zeros = [[0.0] * n_servers for _ in range(n_requests)]
    tables = RequestBlock(first=0, input_transfer_s=zeros, output_transfer_s=zeros,
                          propagation_s=zeros, work_s=work_s.tolist())
    settings = EngineSettings(
        servers=tuple(ServerSpec(slots=1, speed=(1.0, 1.0)) for _ in range(n_servers)),
        contention_levels=1, queue=True, cancel=True, fallback_latency_s=0.0)
    dispatcher = (_RandomSingle(n_servers, np.random.default_rng(dispatch_seq), n_requests)
                  if case == "random-single" else _SendToAll(n_servers))
    result: EngineResult = run_engine(settings, emit_s.tolist(), n_requests, lambda _: tables, dispatcher)
    kept = result.latency_s[int(warmup_fraction * n_requests):]
    return QueueingRun(case, n_requests, utilisation, float(np.mean(kept)),
                       theory_mean_s(case, arrival_rate, service_rate, n_servers))
