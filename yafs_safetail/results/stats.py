"""Statistics of one run's results tables: per-method summaries, speed-ups, β-step averages
(across seeds: ``results.over_seeds``).

Percentiles use numpy's default (``method="linear"``) interpolation; summaries and ratios use the
**test** phase only. A *speed-up of A over B* is ``latency(B) / latency(A)``: > 1 means A is
faster.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import SAFETAIL, sort_methods
from yafs_safetail.results.files import (
    END_REASON_RATE_COLUMNS,
    PERCENTILES,
    PHASES,
    REQUESTS_COLUMNS,
    SUMMARY_COLUMNS,
    _require_columns,
    thin_percentiles_text,
)

# --------------------------------------------------------------------------------------------
# Summary


def _nanmean(values: np.ndarray) -> float:
    finite = values[~np.isnan(values)]
    return float(finite.mean()) if finite.size else math.nan


def _window_means(values: np.ndarray, window: int) -> np.ndarray:
    """Means of consecutive windows of ``window`` values (a shorter last window included)."""
    return np.array([values[i:i + window].mean() for i in range(0, len(values), window)])


def _end_rates(part: pd.DataFrame) -> dict[str, float]:
    """The share of each way a method's requests ended, and their mean energy.

    A requests table from before ``end_reason`` (no failures then) ended every request with a
    reply or, when every copy was refused, with the fallback; it has no energy (NaN).
    """
    if "end_reason" in part.columns:
        reasons = part["end_reason"].to_numpy()
        rates = {column: float(np.mean(reasons == reason)) for reason, column in END_REASON_RATE_COLUMNS.items()}
    else:
        fallback = float(part["fallback"].to_numpy(dtype=float).mean())
        rates = {"success_rate": 1.0 - fallback, "all_refused_rate": fallback,
                 "all_lost_rate": 0.0, "timeout_rate": 0.0}
    energy = part["energy_j"].to_numpy(dtype=float).mean() if "energy_j" in part.columns else math.nan
    return {**rates, "energy_j_per_request": float(energy)}


def summarize(requests: pd.DataFrame, preset: str = "", beta: int | None = None) -> pd.DataFrame:
    """Per-method statistics of the test phase.

    Args:
        requests: a requests table (see ``REQUESTS_COLUMNS``).
        preset: written into the ``preset`` column.
        beta: β; the servers per request averaged over consecutive windows of β test steps (the
            paper's Fig. (e) points) give ``min_window_n_selected``/``max_window_n_selected``
            (NaN when None).

    ``thin_percentiles`` names the percentiles with fewer than 10 test requests beyond them
    (``files.thin_percentiles``), e.g. ``p95;p99``; empty when there are none.

    Returns:
        One row per method with a test row, in report order, columns ``SUMMARY_COLUMNS``.
        Percentiles are numpy's linear interpolation; ``target_met_rate`` is the share of
        requests with latency <= target; ``mean_abs_reward`` ignores NaN rewards (NaN when the
        method records none); ``success_rate``, ``all_refused_rate``, ``all_lost_rate`` and
        ``timeout_rate`` are the shares of each ``end_reason``, ``energy_j_per_request`` the mean
        ``energy_j`` (docs/failures_energy.md).
    """
    _require_columns(requests, REQUESTS_COLUMNS, "requests table")
    test = requests[requests["phase"] == "test"]
    rows = []
    for method in sort_methods(test["method"]):
        part = test[test["method"] == method]
        latency = part["latency_s"].to_numpy(dtype=float)
        n_selected = part["n_selected"].to_numpy(dtype=float)
        p50, p90, p95, p99 = np.percentile(latency, PERCENTILES)
        if beta:
            in_order = part.sort_values("step", kind="stable")["n_selected"].to_numpy(dtype=float)
            windows = _window_means(in_order, beta)
        else:
            windows = np.array([math.nan])
        rows.append({
            "method": method,
            "preset": preset,
            "n_requests": len(part),
            "p50_s": p50,
            "p90_s": p90,
            "p95_s": p95,
            "p99_s": p99,
            "mean_s": latency.mean(),
            "mean_access_rate": part["access_rate"].to_numpy(dtype=float).mean(),
            "mean_n_selected": n_selected.mean(),
            "median_n_selected": float(np.median(n_selected)),
            "min_n_selected": int(n_selected.min()),
            "max_n_selected": int(n_selected.max()),
            "mean_target_s": part["target_s"].to_numpy(dtype=float).mean(),
            "mean_deviation_s": part["deviation_s"].to_numpy(dtype=float).mean(),
            "target_met_rate": float(np.mean(latency <= part["target_s"].to_numpy(dtype=float))),
            "fallback_rate": part["fallback"].to_numpy(dtype=float).mean(),
            "mean_refused": part["refused"].to_numpy(dtype=float).mean(),
            "mean_abs_reward": _nanmean(np.abs(part["reward"].to_numpy(dtype=float))),
            "min_window_n_selected": float(windows.min()),
            "max_window_n_selected": float(windows.max()),
            "thin_percentiles": thin_percentiles_text(len(part)),
            **_end_rates(part),
        })
    frame = pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))
    return frame.astype({"n_requests": "int64", "min_n_selected": "int64",
                         "max_n_selected": "int64"})



# --------------------------------------------------------------------------------------------
# Speed-ups and the paper's claims


def _latency(summary: pd.DataFrame, method: str, percentile: int) -> float:
    # Plain NumPy lookups: a boolean-mask DataFrame copy per call made writing a summary, which
    # asks for hundreds of speed-ups, take most of a second.
    rows = np.flatnonzero(summary["method"].to_numpy() == method)
    if rows.size == 0:
        return math.nan
    return float(summary[f"p{percentile}_s"].to_numpy()[rows[0]])


def speedup(summary: pd.DataFrame, method: str, reference: str, percentile: int) -> float:
    """Speed-up of ``method`` over ``reference`` at a percentile: ``latency(ref) / latency(method)``.

    Returns NaN when either method is absent from ``summary``.
    """
    mine = _latency(summary, method, percentile)
    theirs = _latency(summary, reference, percentile)
    if math.isnan(mine) or math.isnan(theirs) or mine <= 0:
        return math.nan
    return theirs / mine



# --------------------------------------------------------------------------------------------
# β-step averages (Figs. 5-7 (e)-(g))

BETA_COLUMNS: tuple[str, ...] = ("phase", "block", "avg_episode", "value", "n_steps")


def _ordered_rows(requests: pd.DataFrame, method: str, phase: str) -> pd.DataFrame:
    part = requests[(requests["method"] == method) & (requests["phase"] == phase)]
    return part.sort_values("step", kind="stable")


def beta_averages(
    requests: pd.DataFrame,
    beta: int,
    column: str,
    *,
    method: str = SAFETAIL,
    absolute: bool = False,
) -> pd.DataFrame:
    """Averages of ``column`` over consecutive blocks of β steps, as the paper plots them.

    The method's training rows come first, then its test rows, each in step order; blocks
    never straddle the two phases (a phase whose length is not a multiple of β ends in a
    shorter block). A block's ``avg_episode`` is the number of steps up to its end divided by
    β, counting the training steps before the test ones, so full blocks sit at 1, 2, 3, ...
    NaN values (e.g. missing rewards) are left out of a block's mean.

    Args:
        requests: a requests table.
        beta: β, steps per plotted point.
        column: e.g. "access_rate", "deviation_s", "reward".
        method: whose rows to average.
        absolute: average ``|column|`` (for the |reward| plot).

    Returns:
        Columns ``BETA_COLUMNS``: phase, block index within the phase, average episode number,
        the block mean and the block length.
    """
    if beta < 1:
        raise ValueError(f"beta must be >= 1, got {beta}")
    rows = []
    offset = 0
    for phase in PHASES:
        values = _ordered_rows(requests, method, phase)[column].to_numpy(dtype=float)
        if absolute:
            values = np.abs(values)
        for block, start in enumerate(range(0, len(values), beta)):
            chunk = values[start : start + beta]
            rows.append({
                "phase": phase,
                "block": block,
                "avg_episode": (offset + start + len(chunk)) / beta,
                "value": _nanmean(chunk),
                "n_steps": len(chunk),
            })
        offset += len(values)
    return pd.DataFrame(rows, columns=list(BETA_COLUMNS))


def access_rate_by_episode(requests: pd.DataFrame, beta: int) -> pd.DataFrame:
    """SafeTail's β-step average access rate (Fig. (e))."""
    return beta_averages(requests, beta, "access_rate")


def latency_deviation_by_episode(requests: pd.DataFrame, beta: int) -> pd.DataFrame:
    """SafeTail's β-step average latency deviation, target − latency (Fig. (f))."""
    return beta_averages(requests, beta, "deviation_s")


def abs_reward_by_episode(requests: pd.DataFrame, beta: int) -> pd.DataFrame:
    """SafeTail's β-step average of |reward| (Fig. (g))."""
    return beta_averages(requests, beta, "reward", absolute=True)


def train_test_boundary(requests: pd.DataFrame, beta: int, method: str = SAFETAIL) -> float:
    """The average episode number where the method's training ends and testing starts."""
    n_train = int(((requests["method"] == method) & (requests["phase"] == "train")).sum())
    return n_train / beta
