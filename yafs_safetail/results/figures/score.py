"""The scoring suite's figure: the scored policy's p99 over each other method's, per scenario.

One row per scenario (the suite's order, top to bottom), one marker per method set beside the
policy (SafeTail, Oracle, the best fixed method, the strongest simple policy) with its paired
95% interval as a bar, on a log scale around 1: left of the line, the policy's tail is shorter.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS
from yafs_safetail.results.figures.style import STYLE, colour, save_figure

SCORE_FIGURE = "score"
#: The roles drawn, in the legend's order, and the method whose colour each takes.
_ROLE_COLOURS = {"SafeTail": "SafeTail", "Oracle": "Oracle", "best fixed": "MinLoad-2", "least-loaded": "Rand-2"}


def build_score_figure(table: pd.DataFrame, title: str) -> Figure:
    """The figure of a ``results.score_report.score_table``."""
    import matplotlib

    scenarios = list(dict.fromkeys(table["scenario"]))
    roles = [role for role in _ROLE_COLOURS if role in set(table["role"])]
    y = np.arange(len(scenarios))[::-1]
    with matplotlib.rc_context(STYLE):
        figure = Figure(figsize=(7.5, 0.45 * len(scenarios) + 1.6))
        FigureCanvasAgg(figure)
        axes = figure.subplots()
        # The legend's first role on top of each scenario's row, as the legend reads.
        offsets = np.linspace(0.25, -0.25, len(roles)) if len(roles) > 1 else np.zeros(1)
        for offset, role in zip(offsets, roles, strict=True):
            rows = table[table["role"] == role].set_index("scenario").reindex(scenarios)
            ratio = rows["ratio_p99_s"].to_numpy(dtype=float)
            low = ratio - rows["ratio_p99_s_low"].to_numpy(dtype=float)
            high = rows["ratio_p99_s_high"].to_numpy(dtype=float) - ratio
            axes.errorbar(ratio, y + offset, xerr=[low, high], fmt="o", capsize=2, markersize=4,
                          color=colour(_ROLE_COLOURS[role]), label=role)
        axes.axvline(1.0, color="black", linewidth=0.8)
        axes.set_xscale("log")
        axes.set_yticks(y, scenarios)
        axes.set_xlabel("your p99 ÷ theirs (95% paired interval; < 1: yours is faster)")
        axes.grid(True, axis="x", alpha=0.3)
        axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
        axes.set_title(title)
        figure.tight_layout()
    return figure


def draw_score_figure(table: pd.DataFrame, out: Path, title: str,
                      formats: Sequence[str] = DEFAULT_FIGURE_FORMATS) -> list[Path]:
    """Write ``OUT/score.<format>``; returns the files."""
    return save_figure(build_score_figure(table, title), out, SCORE_FIGURE, formats)
