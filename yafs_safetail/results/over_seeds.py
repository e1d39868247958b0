"""Statistics across seeds: intervals that never leave what is possible (a geometric mean with a
Student-t interval on the log scale for ratios, a percentile bootstrap for latencies and
rates), and per-method summaries aggregated over run folders.

One run's statistics (summaries, speed-ups, β-step averages) are ``results.stats``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import sort_methods
from yafs_safetail.results.files import (
    PERCENTILES,
    RUN_FILE,
    SUMMARY_CSV_FILE,
    ResultsFileError,
    read_requests_csv,
    read_summary_csv,
)
from yafs_safetail.results.run_json import RunMetadata, read_run_json
from yafs_safetail.results.stats import speedup, summarize


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


def load_runs(directories: Sequence[str | os.PathLike[str]]) -> list[tuple[RunMetadata, pd.DataFrame]]:
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
    return metrics_over_seeds([summary for _, summary in load_runs(directories)], AGGREGATE_METRICS)


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
