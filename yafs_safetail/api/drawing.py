"""The API's drawing half: one run's figures in memory, each drawn by ``results.figures`` (the
same functions the run's ``figures/`` are drawn with). matplotlib loads on the first call."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

from yafs_safetail.api.reading import RunResults, as_results
from yafs_safetail.api.running import ApiError

if TYPE_CHECKING:
    from matplotlib.figure import Figure


#: The panels of the paper's Figs. 5-7 (one figure per use case; UC1's is Fig. 5).
PAPER_PANELS = "abcdefg"


def paper_figures(results: RunResults | str | os.PathLike[str],
                  panels: str = PAPER_PANELS) -> dict[str, Figure]:
    """The paper's panels (a)-(g) of one run (Fig. 5 for use case 1), in memory.

    The same figures the run writes under ``figures/``
    (``yafs_safetail.results.figures.run_figures``), not written anywhere: a notebook shows each
    one as the value of a cell, ``figure.savefig(path)`` writes it.

    Args:
        results: a :class:`RunResults` or a results folder.
        panels: which of ``"abcdefg"``, in the order wanted (the run's p99-against-energy
            figure is ``yafs_safetail.results.figures.run_figures.build_figures(...)["energy"]``).

    Returns:
        Panel letter to its matplotlib Figure, in the order asked.

    Raises:
        ValueError: an unknown panel letter, or bad results files.
    """
    bad = [p for p in panels if p not in PAPER_PANELS]
    if bad or not panels:
        raise ApiError(f"paper_figures(): panels {panels!r}: expected letters of {PAPER_PANELS!r}")
    from yafs_safetail.results.figures.run_figures import build_figures

    loaded = as_results(results)
    built = build_figures(loaded.requests, loaded.run)
    return {panel: built[panel] for panel in panels}


def latency_cdf(results: RunResults | str | os.PathLike[str], methods: Sequence[str] | None = None,
                phase: str = "test") -> Figure:
    """Each method's empirical latency distribution (CDF) in one phase, on one set of axes.

    The tail is where methods differ, so the y axis is the fraction of requests answered within
    x seconds and the p99 of each method is marked on its curve.

    Args:
        results: a :class:`RunResults` or a results folder.
        methods: the methods to draw, in this order (default: every method, report order).
        phase: ``"test"`` (every method, the same requests) or ``"train"`` (learners only).

    Returns:
        A matplotlib Figure on an Agg canvas (no pyplot state).

    Raises:
        ValueError: an unknown phase or method, or bad results files.
    """
    from yafs_safetail.results import PHASES, sort_methods
    from yafs_safetail.results.figures.run_figures import latency_cdf as draw_latency_cdf

    if phase not in PHASES:
        raise ApiError(f"latency_cdf(): phase {phase!r}: expected one of {', '.join(PHASES)}")
    loaded = as_results(results)
    rows = loaded.requests[loaded.requests["phase"] == phase]
    present = sort_methods(rows["method"])
    chosen = present if methods is None else list(methods)
    missing = [m for m in chosen if m not in present]
    if missing or not chosen:
        raise ApiError(f"latency_cdf(): methods: {missing[0] if missing else 'none given'!r} has no "
                       f"{phase} rows in {loaded.folder}; it has {', '.join(present) or 'none'}")
    return draw_latency_cdf(loaded.requests, loaded.run, chosen, phase, panel=False)
