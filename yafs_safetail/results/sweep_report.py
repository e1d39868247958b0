"""What a sweep's table says: the checks against the sweep's goals, the reports' tables
(SWEEP.md and SEEDS.md for the load sweep, FAILURE_SWEEP.md for the failure sweep, written by
``results.markdown``), and the one writer of a sweep's folder (:meth:`SweepReport.write`; its
figures are ``results.figures.sweeps``'; ``runs.sweep`` computes the table; this module
only reads it).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from yafs_safetail.methods.objectives import objective_named, objective_names
from yafs_safetail.methods.registry import (
    BASELINE_FAMILIES,
    CONTENTION_BASELINES,
    ORACLE,
    parse_method,
)
from yafs_safetail.results.figures.sweeps import plot_failure_sweep, plot_sweep
from yafs_safetail.results.files import write_text_atomic
from yafs_safetail.results.markdown import frame_markdown_table, markdown_table


def _safetail_rows() -> tuple[str, ...]:
    """Every SafeTail a sweep can train, by its rows' method name, the paper's first (each
    objective's, as ``runs.sweep_learners.SAFETAIL_LEARNERS`` names them; asked here, a floor
    below the runs)."""
    return tuple(objective_named(name).method_name for name in objective_names())


def safetail_names(frame: pd.DataFrame) -> list[str]:
    """The SafeTails with rows in ``frame``, the paper's first."""
    present = set(frame["method"])
    return [name for name in _safetail_rows() if name in present]


def is_fixed(method: str) -> bool:
    """Whether ``method`` is one of the built-in fixed methods (Oracle, the x-baselines, Hedge,
    Tied) the goals compare each SafeTail with; a user's own policy (``--method``) is not."""
    family, level = parse_method(method)
    return method == ORACLE or method in CONTENTION_BASELINES or (family in BASELINE_FAMILIES and level is not None)


def fixed_methods(frame: pd.DataFrame) -> list[str]:
    """The built-in fixed methods with rows in ``frame``, in its order."""
    return [name for name in dict.fromkeys(frame["method"]) if is_fixed(name)]


def best_fixed_p99(frame: pd.DataFrame, load: float) -> tuple[str, float]:
    """The built-in fixed method (no SafeTail, no user's policy) with the lowest p99 at ``load``."""
    rows = frame[(frame["load"] == load) & frame["method"].isin(fixed_methods(frame))]
    best = rows.loc[rows["p99_s"].idxmin()]
    return str(best["method"]), float(best["p99_s"])


def sweep_checks(frame: pd.DataFrame) -> list[tuple[str, bool, str]]:
    """The sweep's goals, each as (claim, holds, measured) — computed, never asserted. The
    SafeTail goals are checked for each SafeTail in the sweep, named in the claim."""
    loads = sorted(frame["load"].unique())
    checks: list[tuple[str, bool, str]] = []

    def p99(method: str, load: float) -> float:
        values = frame[(frame["method"] == method) & (frame["load"] == load)]["p99_s"]
        return float(values.iloc[0]) if len(values) else math.nan

    if "Oracle" in set(frame["method"]) and len(loads) > 1:
        low, high = loads[0], loads[-1]
        ratio = p99("Oracle", high) / p99("Oracle", low)
        checks.append((f"Oracle p99 at load {high:g} >= 1.5x at load {low:g}", ratio >= 1.5, f"{ratio:.2f}x"))
        singles = [m for m in frame["method"].unique() if m.endswith("-1")]
        if singles:  # (without a single-dispatch method in the sweep there is nothing to compare)
            worse_at = [load for load in loads if p99("Oracle", load) > min(p99(m, load) for m in singles)]
            checks.append(("Oracle worse than single dispatch beyond some load", bool(worse_at),
                           f"from load {worse_at[0]:g}" if worse_at else "never"))
    has_fixed = bool(fixed_methods(frame))
    for name in safetail_names(frame):
        if len(loads) > 1:  # (one load says nothing of how the copies follow the load)
            copies = [float(frame[(frame["method"] == name) & (frame["load"] == load)]["mean_n_selected"].iloc[0])
                      for load in loads]
            checks.append((f"{name}: fewer copies as load rises", copies[-1] < copies[0],
                           " -> ".join(f"{c:.2f}" for c in copies)))
        for load in loads:
            ours = p99(name, load)
            if has_fixed:
                method, best = best_fixed_p99(frame, load)
                checks.append((f"{name} p99 <= 1.05x best fixed at load {load:g}", ours <= 1.05 * best,
                               f"{ours:.3f} s vs {method} {best:.3f} s ({ours / best:.2f}x)"))
            if load >= 0.7 and "Oracle" in set(frame["method"]):
                checks.append((f"{name} p99 < Oracle's at load {load:g}", ours < p99("Oracle", load),
                               f"{ours:.3f} s vs {p99('Oracle', load):.3f} s"))
    return checks


def seeds_markdown(frames: Mapping[int, pd.DataFrame]) -> str:
    """Several seeds' sweeps (``{seed: sweep.csv's frame}``) side by side: per SafeTail, seed and
    load, its p99 over the best fixed method's and its copies per request (for each SafeTail every
    seed ran, when a fixed method ran too), then each goal of :func:`sweep_checks` with the seeds
    where it holds."""
    seeds = sorted(frames)
    lines: list[str] = []
    names = [name for name in _safetail_rows()
             if all(name in set(frame["method"]) for frame in frames.values())]
    if not all(fixed_methods(frame) for frame in frames.values()):
        names = []  # (no fixed method to compare with)
    for name in names:
        loads = sorted(frames[seeds[0]]["load"].unique())
        lines += [f"Each cell: {name}'s p99 over the best fixed method's (that method), then {name}'s "
                  "copies per request.", ""]
        ratios: dict[float, list[float]] = {load: [] for load in loads}
        rows = []
        for seed in seeds:
            frame = frames[seed]
            cells = [str(seed)]
            for load in loads:
                method, best = best_fixed_p99(frame, load)
                ours = frame[(frame["method"] == name) & (frame["load"] == load)].iloc[0]
                ratios[load].append(float(ours["p99_s"]) / best)
                cells.append(f"{ratios[load][-1]:.2f} ({method}), {ours['mean_n_selected']:.2f}")
            rows.append(cells)
        rows.append(["median (min–max)", *(f"{np.median(r):.2f} ({min(r):.2f}–{max(r):.2f})"
                                           for r in ratios.values())])
        lines += markdown_table(["seed", *(f"{load:g}" for load in loads)], rows)
        lines.append("")
    holds: dict[str, list[int]] = {}
    for seed in seeds:
        for claim, ok, _ in sweep_checks(frames[seed]):
            holds.setdefault(claim, [])
            if ok:
                holds[claim].append(seed)
    lines += markdown_table(["goal", "holds in", "seeds where it holds"],
                           ([claim, f"{len(ok)} of {len(seeds)}", ", ".join(map(str, ok)) or "none"]
                            for claim, ok in holds.items()))
    return "\n".join(lines) + "\n"


def _seconds(value: float) -> str:
    return f"{value:,.0f}" if value >= 100 else f"{value:.2f}"


def _method_tables(frame: pd.DataFrame, x: str,
                   tables: list[tuple[str, Callable[[pd.DataFrame, str, float], str]]]) -> str:
    """One Markdown table per ``(title, cell)`` of ``tables``: a row per value of the axis ``x``,
    a column per method (the SafeTails first); ``cell(rows, method, value)`` writes one cell
    from the point's rows (indexed by method)."""
    names = safetail_names(frame)
    methods = names + [m for m in dict.fromkeys(frame["method"]) if m not in names]
    blocks = []
    for title, cell in tables:
        rows = []
        for value in sorted(frame[x].unique()):
            at = frame[frame[x] == value].set_index("method")
            rows.append([f"{value:g}", *(cell(at, m, value) for m in methods)])
        blocks.append("\n".join([title, "", *markdown_table([x, *methods], rows)]))
    return "\n\n".join(blocks) + "\n"


def glance_markdown(frame: pd.DataFrame) -> str:
    """Every method's p99 and copies per request, one row per load (the SafeTails first, the best
    fixed method's p99 in bold): what sweep.png draws, for the console and SWEEP.md."""
    has_fixed = bool(fixed_methods(frame))
    best = {load: best_fixed_p99(frame, load)[0] for load in frame["load"].unique()} if has_fixed else {}

    def p99(at: pd.DataFrame, method: str, load: float) -> str:
        text = _seconds(at.at[method, "p99_s"])
        return f"**{text}**" if best.get(load) == method else text

    return _method_tables(frame, "load", [
        ("p99 (s; the best fixed method's in bold):", p99),
        ("Copies per request:", lambda at, method, load: f"{at.at[method, 'mean_n_selected']:.2f}")])


def checks_markdown(frame: pd.DataFrame,
                    checks: Callable[[pd.DataFrame], list[tuple[str, bool, str]]] | None = None) -> str:
    """The goals of ``checks`` (default :func:`sweep_checks`, the load sweep's) as a Markdown table."""
    lines = markdown_table(["goal", "holds", "measured"],
                           ([claim, "yes" if ok else "no", measured]
                            for claim, ok, measured in (checks or sweep_checks)(frame)))
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- the failure sweep


#: Oracle's copies for :func:`_redundancy`: more than any x (it sends to every server).
ORACLE_COPIES = 1_000


def _redundancy(method: str) -> int | None:
    """How many copies a fixed method sends every request (Oracle: all; x for the x-baselines;
    None for a method whose copies depend on the request: Hedge, Tied, the SafeTails)."""
    if method == ORACLE:
        return ORACLE_COPIES
    return parse_method(method)[1]


def failure_checks(frame: pd.DataFrame) -> list[tuple[str, bool, str]]:
    """The failure sweep's goals (issue 31), each as (claim, holds, measured), computed from the
    table: at every level with failures, Oracle's and the x >= 2 baselines' success rates above
    every x = 1 baseline's; at every level, each SafeTail's energy per request below Oracle's."""
    levels = sorted(frame["failure_level"].unique())
    methods = list(dict.fromkeys(frame["method"]))

    def value(method: str, level: float, column: str) -> float:
        rows = frame[(frame["method"] == method) & (frame["failure_level"] == level)][column]
        return float(rows.iloc[0]) if len(rows) else math.nan

    checks: list[tuple[str, bool, str]] = []
    singles = [m for m in methods if _redundancy(m) == 1]
    redundant = [m for m in methods if (_redundancy(m) or 0) >= 2]
    if singles and redundant:
        group = " and ".join(([ORACLE] if ORACLE in redundant else [])
                             + (["x >= 2"] if any(m != ORACLE for m in redundant) else []))
        # (At level 0 nothing is lost: every method's success rate is its refusals' alone.)
        for level in (level for level in levels if level > 0):
            low = min(redundant, key=lambda m: value(m, level, "success_rate"))
            high = max(singles, key=lambda m: value(m, level, "success_rate"))
            lowest, highest = value(low, level, "success_rate"), value(high, level, "success_rate")
            checks.append((f"{group} succeed more often than every x = 1 at level {level:g}", lowest > highest,
                           f"lowest {low} {lowest:.4f} vs highest x = 1 {high} {highest:.4f}"))
    if ORACLE in methods:
        for name in safetail_names(frame):
            for level in levels:
                ours, oracle = value(name, level, "energy_j_per_request"), value(ORACLE, level, "energy_j_per_request")
                checks.append((f"{name} energy per request < Oracle's at level {level:g}", ours < oracle,
                               f"{ours:.3g} J vs {oracle:.3g} J ({ours / oracle:.2f}x)"))
    return checks


def failure_glance_markdown(frame: pd.DataFrame) -> str:
    """Every method's success rate, p99 and energy per request, one row per failure level (the
    SafeTails first): what failure_sweep.png draws, for the console and FAILURE_SWEEP.md."""
    return _method_tables(frame, "failure_level", [
        ("Success rate (share of requests a server answered within the time-out):",
         lambda at, method, level: f"{at.at[method, 'success_rate']:.4f}"),
        ("p99 (s):", lambda at, method, level: _seconds(at.at[method, "p99_s"])),
        ("Energy per request (J: the servers' compute and the device's radio):",
         lambda at, method, level: f"{at.at[method, 'energy_j_per_request']:.3g}")])


# ----------------------------------------------------------------------------- a sweep's folder


def write_table(path: Path, frame: pd.DataFrame) -> None:
    """A sweep's CSV table, floats to six significant digits (same rows, same bytes)."""
    write_text_atomic(path, frame.to_csv(index=False, float_format="%.6g"))


@dataclass(frozen=True)
class SweepReport:
    """What a sweep's folder holds besides its points' folders, and how each part is computed
    from the sweep's table.

    Attributes:
        table_file: the assembled table (every point's rows).
        report_file: the Markdown report: the glance, every row, the goals.
        row_columns: the report's "Every row" table's columns.
        glance: the report's first tables (the console prints them too).
        checks: the goals, each (claim, holds, measured).
        plot: draws the figures into a folder, returns their paths.
    """

    table_file: str
    report_file: str
    row_columns: tuple[str, ...]
    glance: Callable[[pd.DataFrame], str]
    checks: Callable[[pd.DataFrame], list[tuple[str, bool, str]]]
    plot: Callable[[pd.DataFrame, Path], list[Path]]

    def markdown(self, frame: pd.DataFrame, heading: str, preface: str) -> str:
        """The report: ``heading``, ``preface`` (how the SafeTails learn, the command), the
        glance, every row and the goals."""
        return (f"# {heading}\n\n" + preface + self.glance(frame) + "\n## Every row\n\n"
                + frame_markdown_table(frame[list(self.row_columns)]) + "\n\n## Goals\n\n"
                + checks_markdown(frame, self.checks))

    def write(self, folder: Path, frame: pd.DataFrame, heading: str, preface: str,
              run_json: Mapping[str, Any]) -> None:
        """The sweep's table, report, figures and ``run.json`` into ``folder``."""
        write_table(folder / self.table_file, frame)
        write_text_atomic(folder / self.report_file, self.markdown(frame, heading, preface))
        self.plot(frame, folder)
        write_text_atomic(folder / "run.json", json.dumps(dict(run_json), indent=1) + "\n")


LOAD_REPORT = SweepReport(
    "sweep.csv", "SWEEP.md", ("load", "method", "n_requests", "p50_s", "p99_s", "mean_n_selected", "fallback_rate"),
    glance_markdown, sweep_checks, plot_sweep)
FAILURE_REPORT = SweepReport(
    "failure_sweep.csv", "FAILURE_SWEEP.md",
    ("failure_level", "method", "n_requests", "success_rate", "p50_s", "p99_s", "mean_n_selected",
     "energy_j_per_request", "share_all_lost", "share_timeout", "share_all_refused"),
    failure_glance_markdown, failure_checks, plot_failure_sweep)
