"""mechanism.png, the training mechanism's figure (``yafs-safetail training-mechanism``), drawn
from mechanism.csv's table (``runs.mechanism.measure_training``).

matplotlib is imported by the drawing function, so importing this module stays light.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd


def mechanism_figure(table: pd.DataFrame, path: Path) -> None:
    """Copies per request (top) and users active per server at dispatch (bottom) against
    training progress, one column per SafeTail, one line per load."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = list(dict.fromkeys(table["method"]))
    figure, axes = plt.subplots(2, len(methods), figsize=(4.2 * len(methods), 6.0), squeeze=False,
                                sharex=True, sharey="row")
    for column, method in enumerate(methods):
        rows = table[table["method"] == method]
        for load, group in rows.groupby("load", sort=True):
            total = float(group["first_request"].iloc[-1] + group["requests"].iloc[-1])
            progress = (group["first_request"] + group["requests"] / 2.0) / total
            axes[0][column].plot(progress, group["mean_copies"], marker="o", markersize=3, label=f"load {load:g}")
            axes[1][column].plot(progress, group["mean_active_per_server"], marker="o", markersize=3)
        axes[0][column].set_title(method)
        axes[1][column].set_xlabel("training progress (share of requests)")
    axes[0][0].set_ylabel("copies per request")
    axes[1][0].set_ylabel("users active per server at dispatch")
    axes[1][0].set_yscale("log")
    axes[0][0].legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
