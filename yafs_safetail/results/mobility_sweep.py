"""The mobility sweep's tables: every method's tail and servers per request at each speed.

A mobility sweep (``yafs-safetail mobility-sweep``, docs/mobility.md) runs the same campaign
run at each named speed (``defaults.MOBILITY_SPEEDS_MPS``) and seed, into
``OUT/<speed>/seed<S>/``. This module reads those folders' test phases and writes:

* ``OUT/mobility.csv``: one row per (speed, method, metric), the mean over seeds and its 95%
  bootstrap interval (``results.over_seeds``): columns :data:`SWEEP_COLUMNS`;
* ``OUT/mobility.md``: p99 and servers per request, a method per row and a speed per column;
* ``OUT/mobility.png`` (``results.figures.mobility``): both against speed, a line per method.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from yafs_safetail.results.files import write_text_atomic
from yafs_safetail.results.over_seeds import INTERVAL_COLUMNS, load_runs, metrics_over_seeds

#: What the sweep reports per method and speed: the test phase's median and p99, and servers per request.
SWEEP_METRICS: tuple[str, ...] = ("p50_s", "p99_s", "mean_n_selected")
SWEEP_COLUMNS: tuple[str, ...] = ("speed", "slowest_mps", "fastest_mps", *INTERVAL_COLUMNS)
SWEEP_CSV = "mobility.csv"
SWEEP_MD = "mobility.md"
#: A run's folder in a sweep: one per speed and seed.
SWEEP_RUN_FOLDER = "{speed}/seed{seed}"


def sweep_folders(out: Path, speeds: Sequence[str], seeds: Sequence[int]) -> dict[str, list[Path]]:
    """Each speed's run folders, in seed order."""
    return {speed: [out / SWEEP_RUN_FOLDER.format(speed=speed, seed=seed) for seed in seeds] for speed in speeds}


def sweep_table(folders: Mapping[str, Sequence[Path]],
                speeds_mps: Mapping[str, tuple[float, float]]) -> pd.DataFrame:
    """Per speed, method and metric (:data:`SWEEP_METRICS`): the mean over the seeds' runs and a
    95% bootstrap interval; speeds in the order given, methods in report order.

    Raises:
        ResultsFileError: a missing or bad run folder.
    """
    parts = []
    for speed, runs in folders.items():
        table = metrics_over_seeds([summary for _, summary in load_runs(runs)], SWEEP_METRICS)
        slowest, fastest = speeds_mps[speed]
        table.insert(0, "fastest_mps", fastest)
        table.insert(0, "slowest_mps", slowest)
        table.insert(0, "speed", speed)
        parts.append(table)
    return pd.concat(parts, ignore_index=True)[list(SWEEP_COLUMNS)]


def _cell(row: pd.Series, digits: int) -> str:
    if math.isnan(row["ci_low"]):
        return f"{row['mean']:.{digits}f}"
    return f"{row['mean']:.{digits}f} [{row['ci_low']:.{digits}f}, {row['ci_high']:.{digits}f}]"


def sweep_markdown(table: pd.DataFrame, title: str) -> str:
    """p99 and servers per request, a method per row and a speed per column."""
    speeds = list(dict.fromkeys(table["speed"]))
    lines = [f"# {title}", ""]
    for metric, heading, digits in (("p99_s", "p99 latency (s)", 3),
                                    ("mean_n_selected", "servers per request", 2)):
        part = table[table["metric"] == metric]
        lines += [f"## {heading}, mean over seeds [95% interval]", "",
                  "| method | " + " | ".join(speeds) + " |", "|---" * (len(speeds) + 1) + "|"]
        for method in dict.fromkeys(part["method"]):
            rows = part[part["method"] == method].set_index("speed")
            cells = [_cell(rows.loc[s], digits) if s in rows.index else "—" for s in speeds]
            lines.append(f"| {method} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def write_sweep_tables(out: Path, table: pd.DataFrame, title: str) -> tuple[Path, Path]:
    """``OUT/mobility.csv`` and ``OUT/mobility.md``, each written whole or not at all."""
    csv_path = write_text_atomic(out / SWEEP_CSV, table.to_csv(index=False, float_format="%.6g"))
    md_path = write_text_atomic(out / SWEEP_MD, sweep_markdown(table, title))
    return csv_path, md_path
