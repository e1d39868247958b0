"""Statistics of results tables: per-method summaries, speed-ups, β-step averages, and
aggregates over seeds with intervals that never leave what is possible.

Percentiles use numpy's default (``method="linear"``) interpolation; summaries and ratios use the
**test** phase only. A *speed-up of A over B* is ``latency(B) / latency(A)``: > 1 means A is
faster.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import SAFETAIL, sort_methods
from yafs_safetail.results.files import (
    END_REASON_RATE_COLUMNS,
    PERCENTILES,
    PHASES,
    REQUESTS_COLUMNS,
    RUN_FILE,
    SUMMARY_COLUMNS,
    SUMMARY_CSV_FILE,
    ResultsFileError,
    _require_columns,
    read_requests_csv,
    read_summary_csv,
    thin_percentiles_text,
)
from yafs_safetail.results.run_json import (
    RunMetadata,
    read_run_json,
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



# --------------------------------------------------------------------------------------------
# Across seeds


def geometric_interval(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Geometric mean of positive values (e.g. ratios over seeds) and a Student-t interval on the
    log scale, which never leaves (0, ∞).

    Returns:
        ``(geometric mean, low, high)``; NaN interval with fewer than two values; all NaN when
        no value is finite and positive.
    """
    data = np.asarray([v for v in values if math.isfinite(v) and v > 0], dtype=float)
    if data.size == 0:
        return math.nan, math.nan, math.nan
    logs = np.log(data)
    centre = float(logs.mean())
    if data.size < 2:
        return math.exp(centre), math.nan, math.nan
    # SciPy is imported only when there is an interval to compute: a single run's summary
    # (one seed) needs none, and the import took over a second of every run.
    from scipy import stats

    half = float(stats.t.ppf((1 + level) / 2, data.size - 1)) * float(logs.std(ddof=1))
    half /= math.sqrt(data.size)
    return math.exp(centre), math.exp(centre - half), math.exp(centre + half)


#: Resamples of :func:`bootstrap_interval` (seeded: the same values give the same interval).
BOOTSTRAP_RESAMPLES = 10_000


def bootstrap_interval(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean over seeds and a percentile-bootstrap interval of it (SciPy), which never leaves the
    range of the values, so a latency or a rate never gets an impossible bound.

    Returns:
        ``(mean, low, high)``; NaN interval with fewer than two values or when they are all
        equal (the interval is then the value itself).
    """
    data = np.asarray([v for v in values if not math.isnan(v)], dtype=float)
    if data.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(data.mean())
    if data.size < 2:
        return mean, math.nan, math.nan
    if np.all(data == data[0]):
        return mean, mean, mean
    from scipy import stats  # only when there is an interval to compute (as above)

    result = stats.bootstrap((data,), np.mean, confidence_level=level, method="percentile",
                             n_resamples=BOOTSTRAP_RESAMPLES, rng=np.random.default_rng(0))
    return mean, float(result.confidence_interval.low), float(result.confidence_interval.high)


def _summary_of_run(folder: Path) -> pd.DataFrame:
    if (folder / SUMMARY_CSV_FILE).is_file():
        return read_summary_csv(folder)
    return summarize(read_requests_csv(folder), beta=read_run_json(folder).beta)


def _load_runs(directories: Sequence[str | os.PathLike[str]]) -> list[tuple[RunMetadata, pd.DataFrame]]:
    if not directories:
        raise ValueError("no run folders given")
    runs = []
    for directory in directories:
        folder = Path(directory)
        if not folder.is_dir():
            raise ResultsFileError(f"{folder}: results folder not found")
        runs.append((read_run_json(folder), _summary_of_run(folder)))
    use_cases = {run.use_case for run, _ in runs}
    if len(use_cases) > 1:
        raise ResultsFileError(
            f"{Path(directories[0]) / RUN_FILE}: key use_case: runs mix use cases "
            f"{sorted(use_cases)}"
        )
    return runs


AGGREGATE_METRICS: tuple[str, ...] = (
    "p50_s", "p90_s", "p95_s", "p99_s", "mean_s", "mean_access_rate", "mean_target_s",
)


def aggregate_summaries(directories: Sequence[str | os.PathLike[str]]) -> pd.DataFrame:
    """Per method and metric, the mean over seeds and a 95% percentile-bootstrap interval.

    Args:
        directories: run folders of one use case (one per seed), each with ``run.json`` and
            ``summary.csv`` (or ``requests.csv``, summarised on the fly).

    Returns:
        Columns ``method, metric, mean, ci_low, ci_high, n_seeds`` (metrics from
        ``AGGREGATE_METRICS``); methods in report order.

    Raises:
        ResultsFileError: a folder or file is missing or bad, or the runs mix use cases.
    """
    return metrics_over_seeds([summary for _, summary in _load_runs(directories)], AGGREGATE_METRICS)


#: What a method's latency table over seeds shows (REPORT.md's users' methods, a campaign's
#: ``latency.md``): the test phase's percentiles and the servers a request went to.
SEED_TABLE_METRICS: tuple[str, ...] = ("p50_s", "p90_s", "p95_s", "p99_s", "mean_n_selected")
#: Columns of :func:`metrics_over_seeds` (and :func:`aggregate_summaries`).
INTERVAL_COLUMNS: tuple[str, ...] = ("method", "metric", "mean", "ci_low", "ci_high", "n_seeds")


def metrics_over_seeds(summaries: Sequence[pd.DataFrame],
                       metrics: Sequence[str] = SEED_TABLE_METRICS,
                       methods: Sequence[str] | None = None) -> pd.DataFrame:
    """Per method and metric, the mean over seeds and a 95% percentile-bootstrap interval
    (:func:`bootstrap_interval`).

    Args:
        summaries: one ``summary.csv`` table per seed (:func:`summarize`), of one setting.
        metrics: ``SUMMARY_COLUMNS`` to aggregate.
        methods: the methods to keep (default: every method of any seed); report order.

    Returns:
        Columns ``INTERVAL_COLUMNS``; ``n_seeds`` counts the seeds that ran the method.
    """
    present = [m for summary in summaries for m in summary["method"]]
    rows = []
    for method in sort_methods(present if methods is None else [m for m in methods if m in present]):
        for metric in metrics:
            values = []
            for summary in summaries:
                part = summary[summary["method"] == method]
                if not part.empty:
                    values.append(float(part[metric].iloc[0]))
            mean, low, high = bootstrap_interval(values)
            rows.append({"method": method, "metric": metric, "mean": mean, "ci_low": low,
                         "ci_high": high, "n_seeds": len(values)})
    return pd.DataFrame(rows, columns=list(INTERVAL_COLUMNS))


#: Columns of :func:`speedups_over_seeds`.
SPEEDUP_INTERVAL_COLUMNS: tuple[str, ...] = (
    "method", "reference", "percentile", "mean", "ci_low", "ci_high", "n_seeds")


def speedups_over_seeds(summaries: Sequence[pd.DataFrame], methods: Sequence[str],
                        references: Sequence[str]) -> pd.DataFrame:
    """Each method's speed-up over each reference at every percentile, computed within each
    seed and combined as :func:`aggregate_speedups` does the paper's ratios: the geometric mean
    over seeds and a 95% t-interval on the log scale (:func:`geometric_interval`).

    Args:
        summaries: one ``summary.csv`` table per seed, of one setting.
        methods: the methods whose speed-ups are wanted (e.g. a user's policies).
        references: what they are compared with (e.g. SafeTail and Oracle); a reference a seed
            did not run gives NaN there, left out of the mean.

    Returns:
        Columns ``SPEEDUP_INTERVAL_COLUMNS``; ``mean`` > 1: the method is faster than the
        reference. ``n_seeds`` counts the seeds with a ratio.
    """
    rows = []
    for method in methods:
        for reference in references:
            if reference == method:
                continue
            for percentile in PERCENTILES:
                values = [speedup(summary, method, reference, percentile) for summary in summaries]
                mean, low, high = geometric_interval(values)
                rows.append({"method": method, "reference": reference, "percentile": percentile,
                             "mean": mean, "ci_low": low, "ci_high": high,
                             "n_seeds": sum(math.isfinite(v) and v > 0 for v in values)})
    return pd.DataFrame(rows, columns=list(SPEEDUP_INTERVAL_COLUMNS))
