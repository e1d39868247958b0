"""compare.png, two results folders side by side (``yafs-safetail compare RUN_A RUN_B``): B / A
per method and figure with the bootstrap intervals, drawn from ``results.compare.compare_runs``'
table.

matplotlib is imported by the drawing functions, so importing this module stays light.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd


def _wrapped(text: str, width_chars: int) -> str:
    """``text`` in lines of at most ``width_chars`` characters, broken anywhere (a long path has
    no spaces to break at)."""
    return "\n".join(text[i:i + width_chars] for i in range(0, len(text), width_chars)) or text


def comparison_figure(table: pd.DataFrame, label_a: str, label_b: str) -> Any:
    """The figure of compare.png (see :func:`plot_comparison`), not yet written.

    The runs' paths, which may be long, go below the axes in full, wrapped to the figure's width;
    the axis label stays short. Constrained layout then keeps every label inside the figure.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from yafs_safetail.results.compare import COMPARED

    methods = list(dict.fromkeys(table["method"]))
    figures = [name for name, _ in COMPARED]
    width_in = max(6.0, 1.1 * len(methods))
    fig = Figure(figsize=(width_in, 4.6), layout="constrained")
    FigureCanvasAgg(fig)
    axis = fig.add_subplot()
    width = 0.8 / len(figures)
    for offset, figure in enumerate(figures):
        rows = table[table["figure"] == figure].set_index("method").loc[methods]
        x = np.arange(len(methods)) + (offset - (len(figures) - 1) / 2) * width
        errors = np.vstack([rows["ratio_b_over_a"] - rows["ratio_low"], rows["ratio_high"] - rows["ratio_b_over_a"]])
        axis.bar(x, rows["ratio_b_over_a"], width, yerr=errors, capsize=2, label=figure)
    axis.axhline(1.0, color="black", linewidth=0.8)
    axis.set_xticks(np.arange(len(methods)), methods, rotation=30, ha="right")
    axis.set_ylabel("B / A  (1 = no difference)")
    paired = "paired " if bool(table["paired"].all()) else ""
    fig.suptitle(f"test phase: run B over run A, 95% {paired}bootstrap intervals")
    # Between the title and the bars, where it hides none of them.
    axis.legend(fontsize=7, ncol=len(figures), loc="lower center", bbox_to_anchor=(0.5, 1.0),
                frameon=False)
    # About 0.55 of the font size per character of a monospace-like path at 8 points.
    chars = max(20, int(width_in * 72 / (0.55 * 8)) - 6)
    fig.supxlabel(f"{_wrapped('A = ' + label_a, chars)}\n{_wrapped('B = ' + label_b, chars)}",
                  fontsize=8, ha="left", x=0.01)
    return fig


def plot_comparison(table: pd.DataFrame, path: Path, label_a: str, label_b: str) -> Path:
    """compare.png: B / A per method and figure, with the intervals (1 = no difference)."""
    fig = comparison_figure(table, label_a, label_b)
    # bbox_inches="tight" as well: whatever a label's length, the file holds all of it.
    fig.savefig(path, dpi=120, metadata={"Software": None}, bbox_inches="tight")
    return path
