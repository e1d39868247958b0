"""The mobility sweep's figure: each method's p99 and servers per request against speed.

Two panels side by side, one line per method (its family's colour, as every figure), the
speeds on the x axis in the sweep's order (at rest, walking, driving: named, not to scale),
95% intervals over seeds as bars.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS
from yafs_safetail.results.figures.style import STYLE, colour, own_methods, save_figure

MOBILITY_FIGURE = "mobility"


def build_mobility_figure(table: pd.DataFrame, title: str) -> Figure:
    """The figure of a :func:`~yafs_safetail.results.mobility_sweep.sweep_table`."""
    import matplotlib

    speeds = list(dict.fromkeys(table["speed"]))
    labels = []
    for speed in speeds:
        row = table[table["speed"] == speed].iloc[0]
        labels.append(f"{speed}\n{row['slowest_mps']:g}-{row['fastest_mps']:g} m/s" if row["fastest_mps"] > 0
                      else f"{speed}\n0 m/s")
    x = np.arange(len(speeds))
    methods = list(dict.fromkeys(table["method"]))
    own = own_methods(methods)
    with matplotlib.rc_context(STYLE):
        figure = Figure(figsize=(11, 4.2))
        FigureCanvasAgg(figure)
        panels = figure.subplots(1, 2)
        for axes, metric, ylabel in ((panels[0], "p99_s", "p99 latency (s)"),
                                     (panels[1], "mean_n_selected", "servers per request")):
            part = table[table["metric"] == metric]
            for method in methods:
                rows = part[part["method"] == method].set_index("speed").reindex(speeds)
                mean = rows["mean"].to_numpy(dtype=float)
                low = np.nan_to_num(mean - rows["ci_low"].to_numpy(dtype=float))
                high = np.nan_to_num(rows["ci_high"].to_numpy(dtype=float) - mean)
                axes.errorbar(x, mean, yerr=[low, high], marker="o", capsize=3, label=method,
                              color=colour(method, own), linewidth=2.2 if method == "SafeTail" else 1.2)
            axes.set_xticks(x, labels)
            axes.set_ylabel(ylabel)
            axes.grid(True, axis="y", alpha=0.3)
        panels[1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small")
        figure.suptitle(title)
        figure.tight_layout()
    return figure


def draw_mobility_figure(table: pd.DataFrame, out: Path, title: str,
                         formats: Sequence[str] = DEFAULT_FIGURE_FORMATS) -> list[Path]:
    """Write ``OUT/mobility.<format>``; returns the files."""
    return save_figure(build_mobility_figure(table, title), out, MOBILITY_FIGURE, formats)
