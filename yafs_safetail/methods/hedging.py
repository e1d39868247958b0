"""Dean & Barroso's "The Tail at Scale" (CACM 2013) requests as baselines: a hedged request (a
second copy only when the first is late, ``dispatch = "hedge"``) and a tied request (two copies
that cancel each other once one starts running, ``dispatch = "tied"``). They only ask for those
modes; a world that does not run them refuses them (``methods.policy.check_dispatch``)."""

from __future__ import annotations

from collections import deque

import numpy as np

from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.policy import Policy, PolicyError
from yafs_safetail.record import RequestRecord

#: Hedge: the percentile of recent latencies after which the second copy goes out.
HEDGE_PERCENTILE = 95.0
#: Hedge: how many recent latencies the percentile is taken over.
HEDGE_WINDOW = 1000
#: Hedge: latencies needed before it hedges at all (before that: one copy, no hedge).
HEDGE_WARMUP = 50
#: Hedge: the percentile is recomputed every this many replies (sorting 1000 values per
#: request would dominate the run).
HEDGE_REFRESH = 25


def rank_servers(observation: Observation) -> np.ndarray:
    """Servers best first: not full, then fewest active users, then nearest (ρ^μ_i)."""
    full = observation.server_active_users >= observation.server_max_load
    return np.lexsort((observation.server_median_propagation_s, observation.server_active_users, full))


class Hedge(Policy):
    """One copy to the best-ranked server; a second to the next-best if no reply has come by
    the running 95th percentile of this method's own recent latencies (or at once if the first
    is refused)."""

    dispatch = "hedge"

    def __init__(self, n_servers: int, rng: np.random.Generator, percentile: float = HEDGE_PERCENTILE) -> None:
        if not 0 < percentile < 100:
            raise PolicyError(f"Hedge: percentile must be in (0, 100), got {percentile!r}")
        self.name = "Hedge"
        super().__init__(n_servers, rng)
        self.percentile = float(percentile)
        self._recent: deque[float] = deque(maxlen=HEDGE_WINDOW)
        self._delay_s = np.inf
        self._since_refresh = 0

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None
        return tuple(rank_servers(observation)[:2].tolist())

    def hedge_delay_s(self) -> float:
        return self._delay_s

    def feedback(self, outcome: RequestRecord) -> None:
        if outcome.fallback:
            return
        self._recent.append(outcome.latency_s)
        self._since_refresh += 1
        if len(self._recent) >= HEDGE_WARMUP and self._since_refresh >= HEDGE_REFRESH:
            self._delay_s = float(np.percentile(np.fromiter(self._recent, float), self.percentile))
            self._since_refresh = 0


class Tied(Policy):
    """Copies to the two best-ranked servers; when one starts running, the other is cancelled
    (the cancellation takes that server's one-way propagation to arrive)."""

    dispatch = "tied"

    def __init__(self, n_servers: int, rng: np.random.Generator) -> None:
        self.name = "Tied"
        super().__init__(n_servers, rng)

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None
        return tuple(rank_servers(observation)[:2].tolist())
