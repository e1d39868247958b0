"""Any :class:`~yafs_safetail.methods.policy.Policy` in the contention world, and what it achieved.

``run_policy(world, policy)`` drives the policy through :func:`~yafs_safetail.contention.engine.run_engine`
(ω^t from the request's world block, the policy's choice checked, a
:class:`~yafs_safetail.record.RequestRecord` as its feedback when it wants one) and returns
per-request arrays; :func:`summarise` turns them into one row of figures.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

# Declared in contention.config, which the sweep commands' options import before NumPy loads.
from yafs_safetail.contention.config import SUMMARY_COLUMNS as SUMMARY_COLUMNS
from yafs_safetail.contention.config import TARGETS as TARGETS
from yafs_safetail.contention.engine import DISPATCH_MODES, EngineResult, FirstReply, run_engine
from yafs_safetail.contention.types import (
    END_ALL_LOST_CODE,
    END_ALL_REFUSED_CODE,
    END_REPLY_CODE,
    END_TIMEOUT_CODE,
)
from yafs_safetail.contention.world import ContentionWorld
from yafs_safetail.methods.policy import (
    DispatchSupport,
    HedgingPolicy,
    Policy,
    PolicyError,
    check_dispatch,
    checked_choice,
    name_a_users_failure,
)
from yafs_safetail.record import RequestRecord

if TYPE_CHECKING:
    import pandas as pd

#: The share of a run's first requests left out of its figures: the servers start empty.
WARMUP_FRACTION = 0.05

#: The contention world runs every mode its engine does.
DISPATCH = DispatchSupport("the contention world", DISPATCH_MODES)


class PolicyDispatcher:
    """The engine's view of a policy: choices checked, records built only when wanted."""

    def __init__(self, world: ContentionWorld, policy: Policy, target: str = "eq4") -> None:
        if target not in TARGETS:
            raise PolicyError(f"target {target!r}: expected one of {', '.join(TARGETS)}")
        check_dispatch(policy, DISPATCH)
        self.world = world
        self.policy = policy
        self.mode = policy.dispatch
        self._hedging = policy if isinstance(policy, HedgingPolicy) else None
        self.wants_outcomes = type(policy).feedback is not Policy.feedback
        self._checked: set[tuple[int, ...]] = set()
        self._n = world.n_servers
        # τ per request in flight, fixed when it is dispatched (observed-load target only).
        self._observed_target_s: dict[int, float] | None = (
            {} if target == "observed-load" and self.wants_outcomes else None)

    def choose(self, request: int, active_users: list[int]) -> Sequence[int]:
        if self._observed_target_s is not None:
            self._observed_target_s[request] = self.world.observed_load_target_s(request, active_users)
        observation = self.world.observation(request, active_users) if self.policy.observes else None
        try:
            chosen = self.policy.choose(observation)
        except Exception as error:
            name_a_users_failure(self.policy, error, f"request {request + 1}")
            raise
        # Checked once per distinct choice (most policies repeat a few): a tuple is looked up
        # as it is, anything else (a list, an array) is checked every time.
        if chosen.__class__ is tuple and chosen in self._checked:
            return chosen
        servers = checked_choice(chosen, self._n, self.policy.name)
        self._checked.add(servers)
        return servers

    def hedge_delay_s(self) -> float:
        assert self._hedging is not None  # check_dispatch: a hedging policy has it
        return self._hedging.hedge_delay_s()

    def completed(self, reply: FirstReply) -> None:
        transfer_s = reply.input_transfer_s + reply.output_transfer_s
        record = RequestRecord(
            method=self.policy.name,
            step=reply.request,
            request_id=reply.request,
            time_emit_s=reply.emit_s,
            latency_s=reply.latency_s,
            target_s=self.world.target_s(reply.request) if self._observed_target_s is None
            else self._observed_target_s.pop(reply.request),
            servers=tuple(sorted(reply.servers)),
            n_servers=self._n,
            refused=reply.refused,
            fallback=reply.fallback,
            winner=reply.winner,
            upload_s=transfer_s,
            propagation_s=2.0 * reply.propagation_s,
            download_s=transfer_s,
            compute_s=reply.server_s,
            lost=reply.lost,
            end_reason=reply.end_reason,
            server_energy_j=reply.server_energy_j,
            radio_energy_j=reply.radio_energy_j,
            saved_energy_j=reply.saved_energy_j,
        )
        self.policy.feedback(record)


@dataclass
class PolicyRun:
    """One method's run in one contention world.

    Attributes:
        method: the policy's name.
        result: the engine's per-request arrays.
        wall_s: wall time of the simulation (including the policy's decisions and learning).
    """

    method: str
    result: EngineResult
    wall_s: float


def run_policy(world: ContentionWorld, policy: Policy, *, queue: bool | None = None,
               cancel: bool | None = None, target: str = "eq4") -> PolicyRun:
    """Every request of ``world`` under ``policy`` (options default to the world's config;
    ``target``: the τ its feedback records carry, one of :data:`TARGETS`)."""
    if policy.n_servers != world.n_servers:
        raise PolicyError(f"{policy.name}: built for {policy.n_servers} servers, the topology has {world.n_servers}")
    started = time.perf_counter()
    result = run_engine(world.engine_settings(queue, cancel), world.emit_s.tolist(),
                        world.config.block_requests, world.block, PolicyDispatcher(world, policy, target))
    return PolicyRun(policy.name, result, time.perf_counter() - started)


def _after_warmup(n: int, warmup_fraction: float) -> slice:
    """The requests a summary counts: all but the first ``warmup_fraction`` (at least one)."""
    return slice(min(int(warmup_fraction * n), n - 1), n)


def request_rows(run: PolicyRun, warmup_fraction: float = WARMUP_FRACTION) -> pd.DataFrame:
    """The requests :func:`summarise` counts, one row each in emission order: ``request`` (its
    index in the run), ``latency_s``, ``n_copies`` and ``energy_j``. Every method of a sweep
    point meets the same requests, so rows of two methods pair by ``request``."""
    import pandas as pd  # only where requests are kept one by one (a scoring suite's points)

    result = run.result
    keep = _after_warmup(result.latency_s.shape[0], warmup_fraction)
    index = np.arange(result.latency_s.shape[0])[keep]
    return pd.DataFrame({"method": run.method, "request": index, "latency_s": result.latency_s[keep],
                         "n_copies": result.n_copies[keep], "energy_j": result.energy_j[keep]})


def summarise(run: PolicyRun, warmup_fraction: float = WARMUP_FRACTION) -> dict[str, float | int | str]:
    """One row of :data:`SUMMARY_COLUMNS` over the requests after the warm-up.

    ``server_s_per_request`` is the server time copies ran, cancelled or not, per request: what
    redundancy costs the servers. ``success_rate`` is the share of requests a reply ended;
    ``share_all_lost``, ``share_timeout`` and ``share_all_refused`` the shares that ended for
    each other reason (``edge.failures.END_REASONS``); ``energy_j_per_request`` the mean of each
    request's servers' and radio energy once all its copies settled.
    """
    result = run.result
    n = result.latency_s.shape[0]
    keep = _after_warmup(n, warmup_fraction)
    latency = result.latency_s[keep]
    end_reason = result.end_reason[keep]
    p50, p90, p95, p99 = np.percentile(latency, [50, 90, 95, 99]).tolist() if latency.size else [math.nan] * 4
    return {
        "method": run.method,
        "n_requests": int(latency.size),
        "p50_s": p50,
        "p90_s": p90,
        "p95_s": p95,
        "p99_s": p99,
        "mean_s": float(np.mean(latency)),
        "mean_n_selected": float(np.mean(result.n_copies[keep])),
        "fallback_rate": float(np.mean(result.fallback[keep])),
        "refused_per_request": float(np.mean(result.refused[keep])),
        "cancelled_per_request": result.cancelled_copies / n,
        "server_s_per_request": result.busy_s / n,
        "success_rate": float(np.mean(end_reason == END_REPLY_CODE)),
        "energy_j_per_request": float(np.mean(result.energy_j[keep])),
        "share_all_lost": float(np.mean(end_reason == END_ALL_LOST_CODE)),
        "share_timeout": float(np.mean(end_reason == END_TIMEOUT_CODE)),
        "share_all_refused": float(np.mean(end_reason == END_ALL_REFUSED_CODE)),
    }
