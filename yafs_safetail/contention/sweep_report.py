"""What a load sweep's table says: the checks against the sweep's goals, SWEEP.md's and
SEEDS.md's tables and the figures (``contention.sweep`` computes the table; this module only
reads it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from yafs_safetail.contention.sweep import SAFETAIL_CA, SAFETAIL_LEARNERS
from yafs_safetail.methods.registry import SAFETAIL


def safetail_names(frame: pd.DataFrame) -> list[str]:
    """The SafeTails with rows in ``frame``, the paper's first."""
    present = set(frame["method"])
    return [name for name in SAFETAIL_LEARNERS.values() if name in present]


def best_fixed_p99(frame: pd.DataFrame, load: float) -> tuple[str, float]:
    """The fixed method (no SafeTail) with the lowest p99 at ``load``."""
    rows = frame[(frame["load"] == load) & ~frame["method"].isin(list(SAFETAIL_LEARNERS.values()))]
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
    has_fixed = bool(set(frame["method"]) - set(SAFETAIL_LEARNERS.values()))
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
    names = [name for name in SAFETAIL_LEARNERS.values()
             if all(name in set(frame["method"]) for frame in frames.values())]
    if not all(set(frame["method"]) - set(SAFETAIL_LEARNERS.values()) for frame in frames.values()):
        names = []  # (no fixed method to compare with)
    for name in names:
        loads = sorted(frames[seeds[0]]["load"].unique())
        lines += [f"Each cell: {name}'s p99 over the best fixed method's (that method), then {name}'s "
                  "copies per request.", "",
                  "| seed | " + " | ".join(f"{load:g}" for load in loads) + " |",
                  "|---|" + "---|" * len(loads)]
        ratios: dict[float, list[float]] = {load: [] for load in loads}
        for seed in seeds:
            frame = frames[seed]
            cells = []
            for load in loads:
                method, best = best_fixed_p99(frame, load)
                ours = frame[(frame["method"] == name) & (frame["load"] == load)].iloc[0]
                ratios[load].append(float(ours["p99_s"]) / best)
                cells.append(f"{ratios[load][-1]:.2f} ({method}), {ours['mean_n_selected']:.2f}")
            lines.append(f"| {seed} | " + " | ".join(cells) + " |")
        lines.append("| median (min–max) | " + " | ".join(
            f"{np.median(r):.2f} ({min(r):.2f}–{max(r):.2f})" for r in ratios.values()) + " |")
        lines.append("")
    holds: dict[str, list[int]] = {}
    for seed in seeds:
        for claim, ok, _ in sweep_checks(frames[seed]):
            holds.setdefault(claim, [])
            if ok:
                holds[claim].append(seed)
    lines += ["| goal | holds in | seeds where it holds |", "|---|---|---|"]
    lines += [f"| {claim} | {len(ok)} of {len(seeds)} | {', '.join(map(str, ok)) or 'none'} |"
              for claim, ok in holds.items()]
    return "\n".join(lines) + "\n"


#: How the figures draw each SafeTail (every fixed method: a thin grey-toned line).
SAFETAIL_STYLE: dict[str, dict[str, Any]] = {
    SAFETAIL: {"color": "tab:red", "label": "SafeTail (paper)"},
    SAFETAIL_CA: {"color": "tab:blue", "label": "SafeTail-CA (contention-aware)"},
}


def _plot_methods(axis: Any, frame: pd.DataFrame, column: str) -> None:
    """One line per method of ``column`` against load: the SafeTails thick and coloured, Oracle
    dashed black, the other fixed methods thin in muted colours."""
    fixed = [m for m in dict.fromkeys(frame["method"]) if m not in SAFETAIL_STYLE]
    muted = ["tab:gray", "tab:olive", "tab:cyan", "tab:brown", "tab:pink", "tab:purple", "tab:orange",
             "tab:green", "darkkhaki", "slategray"]
    for index, method in enumerate(m for m in fixed if m != "Oracle"):
        rows = frame[frame["method"] == method]
        axis.plot(rows["load"], rows[column], marker=".", linewidth=1.0, alpha=0.75,
                  color=muted[index % len(muted)], label=method)
    if "Oracle" in fixed:
        rows = frame[frame["method"] == "Oracle"]
        axis.plot(rows["load"], rows[column], marker="x", linestyle="--", linewidth=1.4, color="black",
                  label="Oracle (all servers)")
    for method, style in SAFETAIL_STYLE.items():
        rows = frame[frame["method"] == method]
        if len(rows):
            axis.plot(rows["load"], rows[column], marker="o", linewidth=3.0, zorder=5, **style)


def plot_sweep(frame: pd.DataFrame, out_dir: Path) -> list[Path]:
    """sweep.png (p99 on a log scale and copies per request against load, every method, both
    SafeTails highlighted) and sweep_latency.png (p50 and p99 against load)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    fig, (latency, copies) = plt.subplots(1, 2, figsize=(12, 4.6))
    _plot_methods(latency, frame, "p99_s")
    latency.set_yscale("log")
    latency.set_ylabel("p99 latency (s, log scale)")
    latency.set_title("p99 latency against load (lower is better)")
    _plot_methods(copies, frame, "mean_n_selected")
    copies.set_ylabel("copies per request")
    copies.set_title("copies sent per request against load")
    for axis in (latency, copies):
        axis.set_xlabel("offered load (utilisation of the slots)")
        axis.grid(True, which="both", alpha=0.3)
    handles, labels = latency.get_legend_handles_labels()
    # The SafeTails (drawn last, on top) head the legend.
    fig.legend(handles[::-1], labels[::-1], loc="center right", fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 0.8, 1))
    written.append(out_dir / "sweep.png")
    fig.savefig(written[-1], dpi=120, metadata={"Software": None})
    plt.close(fig)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharex=True)
    for axis, column, title in ((axes[0], "p50_s", "median"), (axes[1], "p99_s", "p99")):
        _plot_methods(axis, frame, column)
        axis.set_yscale("log")
        axis.set_xlabel("offered load")
        axis.set_ylabel(f"{title} latency (s)")
        axis.set_title(f"{title} latency against load")
        axis.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    written.append(out_dir / "sweep_latency.png")
    fig.savefig(written[-1], dpi=120, metadata={"Software": None})
    plt.close(fig)
    return written


def glance_markdown(frame: pd.DataFrame) -> str:
    """Every method's p99 and copies per request, one row per load (the SafeTails first, the best
    fixed method's p99 in bold): what sweep.png draws, for the console and SWEEP.md."""
    names = safetail_names(frame)
    methods = names + [m for m in dict.fromkeys(frame["method"]) if m not in names]
    header = "| load | " + " | ".join(methods) + " |"
    rule = "|---|" + "---|" * len(methods)
    has_fixed = len(methods) > len(names)

    def seconds(value: float) -> str:
        return f"{value:,.0f}" if value >= 100 else f"{value:.2f}"

    p99_lines = ["p99 (s; the best fixed method's in bold):", "", header, rule]
    copies_lines = ["Copies per request:", "", header, rule]
    for load in sorted(frame["load"].unique()):
        at = frame[frame["load"] == load].set_index("method")
        best = best_fixed_p99(frame, load)[0] if has_fixed else None
        p99_lines.append(f"| {load:g} | " + " | ".join(
            f"**{seconds(at.at[m, 'p99_s'])}**" if m == best else seconds(at.at[m, "p99_s"]) for m in methods) + " |")
        copies_lines.append(f"| {load:g} | " + " | ".join(f"{at.at[m, 'mean_n_selected']:.2f}" for m in methods)
                            + " |")
    return "\n".join(p99_lines) + "\n\n" + "\n".join(copies_lines) + "\n"


def checks_markdown(frame: pd.DataFrame) -> str:
    """The goals of :func:`sweep_checks` as a Markdown table."""
    lines = ["| goal | holds | measured |", "|---|---|---|"]
    lines += [f"| {claim} | {'yes' if ok else 'no'} | {measured} |" for claim, ok, measured in sweep_checks(frame)]
    return "\n".join(lines) + "\n"


def frame_markdown_table(frame: pd.DataFrame) -> str:
    """A Markdown table, floats to three decimals."""
    def cell(value: object) -> str:
        return f"{value:.3f}" if isinstance(value, float | np.floating) else str(value)

    lines = ["| " + " | ".join(frame.columns) + " |", "|" + "---|" * len(frame.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in frame.itertuples(index=False)]
    return "\n".join(lines)
