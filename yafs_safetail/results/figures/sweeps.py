"""A contention sweep's figures, drawn from its table (sweep.csv or failure_sweep.csv's frame):
sweep.png and sweep_latency.png for the load sweep, failure_sweep.png for the failure sweep
(``results.sweep_report.SweepReport`` writes them with the rest of a sweep's folder).

matplotlib is imported by the drawing functions, so importing this module stays light.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from yafs_safetail.methods.objectives import objective_named
from yafs_safetail.methods.registry import SAFETAIL

#: How the figures draw each SafeTail (every fixed method: a thin grey-toned line); the names are
#: the sweeps' (each objective's method name).
SAFETAIL_STYLE: dict[str, dict[str, Any]] = {
    SAFETAIL: {"color": "tab:red", "label": "SafeTail (paper)"},
    objective_named("value").method_name: {"color": "tab:blue", "label": "SafeTail-CA (contention-aware)"},
    objective_named("q-target").method_name: {"color": "tab:purple",
                                              "label": "SafeTail-Q (the original code's targets)"},
}


def _plot_methods(axis: Any, frame: pd.DataFrame, column: str, x: str = "load") -> None:
    """One line per method of ``column`` against ``x`` (the sweep's axis): the SafeTails thick
    and coloured, Oracle dashed black, the other fixed methods thin in muted colours."""
    fixed = [m for m in dict.fromkeys(frame["method"]) if m not in SAFETAIL_STYLE]
    muted = ["tab:gray", "tab:olive", "tab:cyan", "tab:brown", "tab:pink", "tab:purple", "tab:orange",
             "tab:green", "darkkhaki", "slategray"]
    for index, method in enumerate(m for m in fixed if m != "Oracle"):
        rows = frame[frame["method"] == method]
        axis.plot(rows[x], rows[column], marker=".", linewidth=1.0, alpha=0.75,
                  color=muted[index % len(muted)], label=method)
    if "Oracle" in fixed:
        rows = frame[frame["method"] == "Oracle"]
        axis.plot(rows[x], rows[column], marker="x", linestyle="--", linewidth=1.4, color="black",
                  label="Oracle (all servers)")
    for method, style in SAFETAIL_STYLE.items():
        rows = frame[frame["method"] == method]
        if len(rows):
            axis.plot(rows[x], rows[column], marker="o", linewidth=3.0, zorder=5, **style)


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


def plot_failure_sweep(frame: pd.DataFrame, out_dir: Path) -> list[Path]:
    """failure_sweep.png: success rate, p99 (log scale) and energy per request against the
    failure level, one line per method, both SafeTails highlighted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    panels = (("success_rate", "success rate", "requests answered (higher is better)"),
              ("p99_s", "p99 latency (s, log scale)", "p99 latency (lower is better)"),
              ("energy_j_per_request", "energy per request (J)", "energy per request (lower is better)"))
    for axis, (column, label, title) in zip(axes, panels, strict=True):
        _plot_methods(axis, frame, column, x="failure_level")
        axis.set_xlabel("each server's probability of being down")
        axis.set_ylabel(label)
        axis.set_title(title)
        axis.grid(True, which="both", alpha=0.3)
    axes[1].set_yscale("log")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles[::-1], labels[::-1], loc="center right", fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 0.85, 1))
    written = out_dir / "failure_sweep.png"
    fig.savefig(written, dpi=120, metadata={"Software": None})
    plt.close(fig)
    return [written]
