"""Two results folders side by side: every method's test-phase percentiles in each, and the
ratio B / A with a bootstrap 95% interval (``yafs-safetail compare RUN_A RUN_B``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import sort_methods
from yafs_safetail.results.files import ResultsFileError, read_requests_csv

#: The figures compared, as (column name, percentile or None for the mean servers per request).
COMPARED: tuple[tuple[str, float | None], ...] = (
    ("p50_s", 50.0), ("p90_s", 90.0), ("p95_s", 95.0), ("p99_s", 99.0), ("mean_n_selected", None),
)
#: Bootstrap resamples per interval.
BOOTSTRAP_RESAMPLES = 1000
COMPARE_COLUMNS = ("method", "figure", "run_a", "run_b", "ratio_b_over_a", "ratio_low", "ratio_high")


def _figure(values: np.ndarray, percentile: float | None) -> np.ndarray:
    """The figure over the last axis (a percentile of latencies, or a mean)."""
    return np.mean(values, axis=-1) if percentile is None else np.percentile(values, percentile, axis=-1)


def _bootstrap_ratio(a: np.ndarray, b: np.ndarray, percentile: float | None,
                     rng: np.random.Generator) -> tuple[float, float]:
    """A 95% percentile-bootstrap interval of figure(B) / figure(A), each run resampled on its
    own (the requests of two runs are not paired). Always within the ratios' feasible range."""
    ratios = np.empty(BOOTSTRAP_RESAMPLES)
    chunk = 100  # resamples drawn at once: bounded memory for long runs
    for start in range(0, BOOTSTRAP_RESAMPLES, chunk):
        size = min(chunk, BOOTSTRAP_RESAMPLES - start)
        fa = _figure(a[rng.integers(a.size, size=(size, a.size))], percentile)
        fb = _figure(b[rng.integers(b.size, size=(size, b.size))], percentile)
        ratios[start:start + size] = fb / fa
    low, high = np.percentile(ratios, [2.5, 97.5])
    return float(low), float(high)


def compare_runs(run_a: Path, run_b: Path, seed: int = 0) -> pd.DataFrame:
    """One row per (method in both runs, figure): A's value, B's, B / A and its interval.

    Raises:
        ResultsFileError: a folder without a readable ``requests.csv``, or no method in common.
    """
    frames = [read_requests_csv(run) for run in (run_a, run_b)]
    tests = [frame[frame["phase"] == "test"] for frame in frames]
    common = sort_methods(set(tests[0]["method"]) & set(tests[1]["method"]))
    if not common:
        raise ResultsFileError(f"{run_a} and {run_b}: no method in common in their test phases")
    rng = np.random.default_rng(seed)
    rows = []
    for method in common:
        columns = []
        for test in tests:
            rows_of = test[test["method"] == method]
            columns.append((rows_of["latency_s"].to_numpy(float), rows_of["n_selected"].to_numpy(float)))
        for name, percentile in COMPARED:
            index = 1 if percentile is None else 0
            a, b = columns[0][index], columns[1][index]
            value_a, value_b = float(_figure(a, percentile)), float(_figure(b, percentile))
            ratio = value_b / value_a if value_a > 0 else math.nan
            low, high = _bootstrap_ratio(a, b, percentile, rng) if value_a > 0 else (math.nan, math.nan)
            rows.append((method, name, value_a, value_b, ratio, low, high))
    return pd.DataFrame(rows, columns=list(COMPARE_COLUMNS))


def plot_comparison(table: pd.DataFrame, path: Path, label_a: str, label_b: str) -> Path:
    """compare.png: B / A per method and figure, with the intervals (1 = no difference)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = list(dict.fromkeys(table["method"]))
    figures = [name for name, _ in COMPARED]
    fig, axis = plt.subplots(figsize=(max(6.0, 1.1 * len(methods)), 4.2))
    width = 0.8 / len(figures)
    for offset, figure in enumerate(figures):
        rows = table[table["figure"] == figure].set_index("method").loc[methods]
        x = np.arange(len(methods)) + (offset - (len(figures) - 1) / 2) * width
        errors = np.vstack([rows["ratio_b_over_a"] - rows["ratio_low"], rows["ratio_high"] - rows["ratio_b_over_a"]])
        axis.bar(x, rows["ratio_b_over_a"], width, yerr=errors, capsize=2, label=figure)
    axis.axhline(1.0, color="black", linewidth=0.8)
    axis.set_xticks(np.arange(len(methods)), methods, rotation=30, ha="right")
    axis.set_ylabel(f"B / A  (A = {label_a}, B = {label_b})", fontsize=8)
    axis.set_title("test phase: run B over run A, 95% bootstrap intervals")
    axis.legend(fontsize=7, ncol=len(figures))
    fig.tight_layout()
    fig.savefig(path, dpi=120, metadata={"Software": None})
    plt.close(fig)
    return path
