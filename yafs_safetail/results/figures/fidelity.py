"""The fidelity scorecard's figure (``fidelity-<preset>.png`` in a reproduction's folder): the
paper's value against ours per ratio, drawn from ``results.fidelity.scorecard``'s table.

matplotlib is imported by the drawing function, so importing this module stays light.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS


def draw_scorecard(card: pd.DataFrame, stem: Path,
                   formats: Sequence[str] = DEFAULT_FIGURE_FORMATS) -> list[Path]:
    """The paper's value against ours per ratio, log-log, identity line and ±20% band;
    calibration and held-out ratios marked. Writes ``stem``.png and/or ``stem``.pdf (``formats``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from yafs_safetail.results.fidelity import TOLERANCE

    ratios = card[card["kind"] == "ratio"]
    fig, ax = plt.subplots(figsize=(5.2, 5.0))
    values = np.concatenate([ratios["paper"].to_numpy(float), ratios["ours"].to_numpy(float),
                             ratios["ci_low"].dropna().to_numpy(float),
                             ratios["ci_high"].dropna().to_numpy(float)])
    values = values[np.isfinite(values) & (values > 0)]
    low, high = (values.min() / 1.3, values.max() * 1.3) if values.size else (0.5, 3.0)
    grid = np.geomspace(low, high, 50)
    ax.fill_between(grid, grid * (1 - TOLERANCE), grid * (1 + TOLERANCE), color="0.88",
                    label=f"±{TOLERANCE:.0%}")
    ax.plot(grid, grid, color="0.4", linewidth=1, label="ours = paper")
    styles = {"calibration": ("s", "tab:orange", "calibration subset"),
              "held-out": ("o", "tab:blue", "held out")}
    for subset, (marker, colour, label) in styles.items():
        part = ratios[ratios["subset"] == subset]
        if part.empty:
            continue
        ours = part["ours"].to_numpy(float)
        err = np.vstack([ours - part["ci_low"].fillna(part["ours"]).to_numpy(float),
                         part["ci_high"].fillna(part["ours"]).to_numpy(float) - ours])
        ax.errorbar(part["paper"], ours, yerr=err, fmt=marker, color=colour, markersize=5,
                    capsize=2, linewidth=0.8, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(low, high)
    ax.set_ylim(low, high)
    ax.set_xlabel("paper's ratio")
    ax.set_ylabel("our ratio (geometric mean over seeds, 95% interval)")
    ax.set_title("Published ratios: paper vs this project")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    written = []
    for suffix in (f".{fmt}" for fmt in formats):
        path = stem.with_suffix(suffix)
        fig.savefig(path, dpi=150, metadata={"CreationDate": None} if suffix == ".pdf" else None)
        written.append(path)
    plt.close(fig)
    return written
