"""How a contention server's running copies share its CPU, and what that makes of τ.

:func:`compute_speed_table` gives each running job's speed for every number of jobs: the
servers' processor sharing (``ContentionWorld.engine_settings``). :class:`ObservedLoadTarget`
reads Eq. 4's compute term at the load a request sees instead of at ν (the ``observed-load``
target, beyond the paper: docs/deviations.md D12), with the same speeds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def compute_speed_table(median_compute_by_k_s: np.ndarray, speed_factor: float, max_jobs: int) -> tuple[float, ...]:
    """Per-job speed for 0..max_jobs running jobs: T(1)/T(n) × the server's speed factor.

    T(n) beyond the traced k grows in proportion to n (the server is then simply divided).
    """
    traced = np.asarray(median_compute_by_k_s, dtype=float)
    k_max = traced.shape[0]
    speeds = [speed_factor]  # n = 0 is never used for progress; any positive value will do
    for n in range(1, max_jobs + 1):
        time_n = traced[n - 1] if n <= k_max else traced[-1] * n / k_max
        speeds.append(speed_factor * float(traced[0] / time_n))
    return tuple(speeds)


class ObservedLoadTarget:
    """τ with its compute term at the servers' observed load (D12).

    Eq. 4 takes the median compute time at ν parallel instances, ν standing for how many
    instances a server usually runs. Here that number is seen: with m the median over servers
    of ℓ_i (our running and waiting copies and the background tenants), a new copy is one of
    m + 1 jobs; up to the slots c (the servers' median capacity) they share the CPU, so the
    compute term is C(s_j) × T(m + 1) / T(ν); beyond c, the copy also waits for
    (m + 1 - c) / c rounds of T(c). T(k) is the traces' median compute time at k processes, in
    proportion to k beyond the traced k, as the servers' speed tables take it.
    """

    def __init__(self, capacity: Sequence[int], median_compute_by_k_s: np.ndarray) -> None:
        """Args:
        capacity: each server's slots.
        median_compute_by_k_s: the traces' median compute time at k = 1.. processes.
        """
        self.slots = max(1, int(np.median(capacity)))
        traced_s = np.asarray(median_compute_by_k_s, dtype=float)
        speeds = compute_speed_table(traced_s, 1.0, max(self.slots, len(traced_s)))
        # T(k) for k = 0..max(c, traced k) (T(0) unused): T(1) / speed(k).
        self.processes_s = tuple(float(traced_s[0]) / speed for speed in speeds)

    def target_s(self, eq4_target_s: float, compute_s: float, nu: int, active_users: Sequence[int]) -> float:
        """Eq. 4's τ of a request (``eq4_target_s``, whose compute term is ``compute_s`` at ν)
        with that term read at ``active_users`` instead."""
        slots, processes_s = self.slots, self.processes_s
        # The median of the servers' ℓ_i without numpy (per request): the middle one, or the
        # two middle ones' mean rounded down.
        ordered = sorted(active_users)
        half = len(ordered) // 2
        jobs = (ordered[half] + ordered[~half]) // 2 + 1
        effective_s = processes_s[min(jobs, slots)] * (1.0 + max(0, jobs - slots) / slots)
        return eq4_target_s - compute_s + compute_s * effective_s / processes_s[nu]
