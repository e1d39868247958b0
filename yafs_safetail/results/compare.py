"""Two results folders side by side: every method's test-phase percentiles in each, and the
ratio B / A with a bootstrap 95% interval (``yafs-safetail compare RUN_A RUN_B``).

Two runs of one world and seed meet the same test requests (common random numbers): their
intervals are then paired, each resample drawing the same requests from both runs, so the
interval measures the methods' difference, not the requests' spread. A run against itself gives
1 with a zero-width interval. Otherwise each run is resampled on its own.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import sort_methods
from yafs_safetail.results.figures.compare import comparison_figure as comparison_figure
from yafs_safetail.results.figures.compare import plot_comparison as plot_comparison
from yafs_safetail.results.files import ResultsFileError, read_requests_csv
from yafs_safetail.results.run_json import read_run_json

#: The figures compared, as (column name, percentile or None for the mean servers per request).
COMPARED: tuple[tuple[str, float | None], ...] = (
    ("p50_s", 50.0), ("p90_s", 90.0), ("p95_s", 95.0), ("p99_s", 99.0), ("mean_n_selected", None),
)
#: Bootstrap resamples per interval.
BOOTSTRAP_RESAMPLES = 1000
COMPARE_COLUMNS = ("method", "figure", "run_a", "run_b", "ratio_b_over_a", "ratio_low", "ratio_high",
                   "paired")


#: The ``run.json`` keys that say which world a run's requests met: two runs differing in one of
#: them do not measure their methods on the same requests, servers and loads, so B / A mixes the
#: methods' difference with the worlds'. The seed is not among them (comparing seeds is a use of
#: the command), nor the learner's settings (comparing them is its main use).
WORLD_KEYS = ("use_case", "preset", "topology", "placement", "n_servers", "step_interval_s", "world",
              "failures", "energy")
#: Keys naming input files: compared by file name, since each run records the path as it was typed
#: from its own working folder.
FILE_KEYS = ("topology", "placement", "down_file")
#: How many differences the warning spells out before it counts the rest.
SHOWN_DIFFERENCES = 4


def _flat(value: Any, key: str) -> Iterator[tuple[str, Any]]:
    """``(dotted key, value)`` for every leaf of a run.json value (``world.load_peak_users``)."""
    if isinstance(value, Mapping):
        for name in sorted(value):
            yield from _flat(value[name], f"{key}.{name}")
    else:
        leaf = key.rsplit(".", 1)[-1]
        yield key, Path(value).name if leaf in FILE_KEYS and isinstance(value, str) else value


def _world_of(run: Path) -> dict[str, Any]:
    recorded = json.loads(read_run_json(run).to_json())  # checked, extra keys included
    return dict(item for key in WORLD_KEYS if key in recorded for item in _flat(recorded[key], key))


def world_differences(run_a: Path, run_b: Path) -> list[str]:
    """What differs between the worlds two results folders ran in, one ``key A vs B`` each.

    Reads both ``run.json`` files (:data:`WORLD_KEYS`, nested settings by dotted key; a key one
    run lacks, written by an older version, is not counted as a difference).

    Raises:
        ResultsFileError: a folder without a readable ``run.json``.
    """
    a, b = _world_of(run_a), _world_of(run_b)
    return [f"{key} {json.dumps(a[key])} vs {json.dumps(b[key])}"
            for key in a if key in b and a[key] != b[key]]


def world_warning(run_a: Path, run_b: Path) -> str | None:
    """The one-line warning ``compare`` prints when the two runs' worlds differ, else None."""
    try:
        differences = world_differences(run_a, run_b)
    except ResultsFileError as error:  # the table may still be read; say what is unknown
        return f"cannot tell whether the two runs share a world: {error}"
    if not differences:
        return None
    shown = "; ".join(differences[:SHOWN_DIFFERENCES])
    more = len(differences) - SHOWN_DIFFERENCES
    if more > 0:
        shown += f"; and {more} more"
    return (f"{run_a} and {run_b} ran in different worlds ({shown}): B / A mixes the methods' "
            "difference with the worlds'")


def _figure(values: np.ndarray, percentile: float | None) -> np.ndarray:
    """The figure over the last axis (a percentile of latencies, or a mean)."""
    return np.mean(values, axis=-1) if percentile is None else np.percentile(values, percentile, axis=-1)


def _bootstrap_ratio(a: np.ndarray, b: np.ndarray, percentile: float | None,
                     rng: np.random.Generator, paired: bool = False) -> tuple[float, float]:
    """A 95% percentile-bootstrap interval of figure(B) / figure(A). Paired (``a[i]`` and
    ``b[i]`` the same request): each resample takes the same requests from both. Unpaired: each
    run resampled on its own. Always within the ratios' feasible range."""
    ratios = np.empty(BOOTSTRAP_RESAMPLES)
    chunk = 100  # resamples drawn at once: bounded memory for long runs
    for start in range(0, BOOTSTRAP_RESAMPLES, chunk):
        size = min(chunk, BOOTSTRAP_RESAMPLES - start)
        picks_a = rng.integers(a.size, size=(size, a.size))
        picks_b = picks_a if paired else rng.integers(b.size, size=(size, b.size))
        ratios[start:start + size] = _figure(b[picks_b], percentile) / _figure(a[picks_a], percentile)
    low, high = np.percentile(ratios, [2.5, 97.5])
    return float(low), float(high)


def same_requests(run_a: Path, run_b: Path) -> bool:
    """Whether two runs' test phases met the same requests: the same seed and world in both
    ``run.json`` files (common random numbers). False when either cannot be read."""
    try:
        seeds = [read_run_json(run).seed for run in (run_a, run_b)]
        return seeds[0] == seeds[1] and not world_differences(run_a, run_b)
    except ResultsFileError:
        return False


def _by_request(rows: pd.DataFrame) -> pd.DataFrame:
    return rows.sort_values("request_id", kind="stable")


def compare_runs(run_a: Path, run_b: Path, seed: int = 0) -> pd.DataFrame:
    """One row per (method in both runs, figure): A's value, B's, B / A and its interval, and
    whether the interval is paired (:func:`same_requests`, and the method's test phase holds the
    same request ids in both runs).

    Raises:
        ResultsFileError: a folder without a readable ``requests.csv``, or no method in common.
    """
    frames = [read_requests_csv(run) for run in (run_a, run_b)]
    tests = [frame[frame["phase"] == "test"] for frame in frames]
    common = sort_methods(set(tests[0]["method"]) & set(tests[1]["method"]))
    if not common:
        raise ResultsFileError(f"{run_a} and {run_b}: no method in common in their test phases")
    one_world = same_requests(run_a, run_b)
    rng = np.random.default_rng(seed)
    rows = []
    for method in common:
        of_a, of_b = (test[test["method"] == method] for test in tests)
        paired = False
        if one_world:
            sorted_a, sorted_b = _by_request(of_a), _by_request(of_b)
            ids = sorted_a["request_id"].to_numpy()
            paired = (np.array_equal(ids, sorted_b["request_id"].to_numpy())
                      and len(np.unique(ids)) == len(ids))
            if paired:  # row i of both is the same request
                of_a, of_b = sorted_a, sorted_b
        for name, percentile in COMPARED:
            column = "n_selected" if percentile is None else "latency_s"
            a, b = of_a[column].to_numpy(float), of_b[column].to_numpy(float)
            value_a, value_b = float(_figure(a, percentile)), float(_figure(b, percentile))
            ratio = value_b / value_a if value_a > 0 else math.nan
            low, high = (_bootstrap_ratio(a, b, percentile, rng, paired) if value_a > 0
                         else (math.nan, math.nan))
            rows.append((method, name, value_a, value_b, ratio, low, high, paired))
    return pd.DataFrame(rows, columns=list(COMPARE_COLUMNS))
