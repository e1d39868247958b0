"""Figures across seeds: one use case and preset over several run folders, with 95% bands.

A reproduction (``yafs-safetail reproduce``, through :mod:`yafs_safetail.results.reproduction`)
draws two per use case and preset into ``OUT/figures/``, each in the formats asked
(``--figure-format``, PNG by default):

* ``uc<N>-<preset>-latency-bands``: per method, the median, p90, p95 and p99 latency of the test
  phase as the mean over seeds of each seed's percentile, shaded with the 95% percentile-
  bootstrap interval of that mean (:func:`results.bootstrap_interval`, through
  :func:`results.aggregate_summaries`, the numbers of REPORT.md's latency table); one panel per
  baseline family (SafeTail, Oracle and users' methods in each), the average target dashed;
* ``uc<N>-<preset>-servers-bands``: SafeTail's servers per request averaged over each β steps
  (the points of Fig. (e), in servers rather than as a share), training then testing, as the
  mean over seeds per block with the same kind of band.

A bootstrap interval of a mean never leaves the range of the seeds' values, so a band never
shows an impossible latency or server count. With one seed there is no interval and no band.

The drawing follows one run's figures (:mod:`.run_figures`: object API on the Agg canvas) with
the same style, colours and file writing (:mod:`.style`). The data behind each band are
public functions (:func:`latency_bands`, :func:`servers_bands`), so what is drawn can be checked
against what was computed.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from yafs_safetail import results
from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS
from yafs_safetail.results import ResultsFileError
from yafs_safetail.results.figures.style import (
    PHASE_COLOURS,
    STYLE,
    colour,
    own_methods,
    save_figure,
)
from yafs_safetail.results.paper import PERCENTILE_NAMES

LATENCY_BANDS_STEM = "uc{use_case}-{preset}-latency-bands"
SERVERS_BANDS_STEM = "uc{use_case}-{preset}-servers-bands"

LATENCY_BAND_COLUMNS: tuple[str, ...] = (
    "method", "percentile", "mean_s", "ci_low_s", "ci_high_s", "n_seeds",
)
SERVERS_BAND_COLUMNS: tuple[str, ...] = (
    "phase", "block", "avg_episode", "mean", "ci_low", "ci_high", "n_seeds",
)
#: The gid of each band's PolyCollection: "band:<method>" / "band:<phase>", so that tests and
#: users can find a band among the artists.
BAND_GID = "band:{name}"
_BAND_ALPHA = 0.2


@dataclass(frozen=True, slots=True)
class SeedSeries:
    """What the figures say about the runs they summarise (titles and footers).

    Attributes:
        use_case, use_case_name, preset: shared by every run.
        seeds: the runs' seeds, in the order given.
        beta: β of the runs (steps per point of the servers figure).
        n_servers: servers in the runs' topology (the servers axis ends there).
        package_version: of the first run.
    """

    use_case: int
    use_case_name: str
    preset: str
    seeds: tuple[int, ...]
    beta: int
    n_servers: int
    package_version: str


def latency_bands(stats: pd.DataFrame) -> pd.DataFrame:
    """The latency figure's data: per method and percentile, the mean over seeds and its band.

    Args:
        stats: from :func:`results.aggregate_summaries` (its bootstrap intervals are the bands).

    Returns:
        Columns ``LATENCY_BAND_COLUMNS``; methods in report order, percentiles ascending. The
        interval columns are NaN with one seed.
    """
    rows = []
    for method in results.sort_methods(stats["method"]):
        part = stats[stats["method"] == method].set_index("metric")
        for percentile in results.PERCENTILES:
            entry = part.loc[f"p{percentile}_s"]
            rows.append({"method": method, "percentile": percentile, "mean_s": entry["mean"],
                         "ci_low_s": entry["ci_low"], "ci_high_s": entry["ci_high"],
                         "n_seeds": int(entry["n_seeds"])})
    return pd.DataFrame(rows, columns=list(LATENCY_BAND_COLUMNS))


def servers_bands(requests_by_seed: Sequence[pd.DataFrame], beta: int) -> pd.DataFrame:
    """The servers figure's data: SafeTail's β-step mean servers per request, over seeds.

    Each seed's SafeTail rows are cut into β-step blocks as for Fig. (e)
    (:func:`results.beta_averages` of ``n_selected``); blocks are matched across seeds by phase
    and index, and each block gets the mean over seeds and a 95% percentile-bootstrap interval
    (:func:`results.bootstrap_interval`).

    Args:
        requests_by_seed: one requests table per seed.
        beta: β, steps per block.

    Returns:
        Columns ``SERVERS_BAND_COLUMNS``, training blocks first, then test blocks, each in
        order. ``avg_episode`` is the mean over the seeds that have the block (runs of one
        reproduction share their budget, so it is the same in all of them).
    """
    curves = [results.beta_averages(requests, beta, "n_selected") for requests in requests_by_seed]
    rows = []
    for phase in results.PHASES:
        blocks = sorted({int(b) for curve in curves for b in curve.loc[curve["phase"] == phase, "block"]})
        for block in blocks:
            matched = [curve[(curve["phase"] == phase) & (curve["block"] == block)]
                       for curve in curves]
            matched = [m for m in matched if not m.empty]
            values = [float(m["value"].iloc[0]) for m in matched]
            mean, low, high = results.bootstrap_interval(values)
            rows.append({
                "phase": phase, "block": block,
                "avg_episode": float(np.mean([float(m["avg_episode"].iloc[0]) for m in matched])),
                "mean": mean, "ci_low": low, "ci_high": high,
                "n_seeds": sum(not math.isnan(v) for v in values),
            })
    return pd.DataFrame(rows, columns=list(SERVERS_BAND_COLUMNS))


def _new_figure(series: SeedSeries, title: str, n_panels: int = 1) -> tuple[Figure, list[Axes]]:
    figure = Figure(figsize=(max(5.2, 3.3 * n_panels), 3.6))
    figure.subplots_adjust(left=0.08 if n_panels > 1 else 0.12, right=0.98, bottom=0.17,
                           top=0.82, wspace=0.08)
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(1, n_panels, sharey=True, squeeze=False)[0])
    figure.suptitle(f"{title}\nuse case {series.use_case}, preset {series.preset}, "
                    f"{len(series.seeds)} seed(s); shaded: 95% bootstrap interval over seeds",
                    fontsize=9)
    seeds = ", ".join(map(str, series.seeds))
    figure.text(0.99, 0.005, f"{series.use_case_name}; seeds {seeds}, β = {series.beta}, "
                f"yafs-safetail {series.package_version}",
                ha="right", va="bottom", fontsize=6, color="#777777", wrap=True)
    return figure, axes


def _band(axes: Axes, x: np.ndarray, low: np.ndarray, high: np.ndarray, band_colour: str,
          name: str) -> None:
    # With one seed there is no interval (NaN): draw no band rather than a zero-width one.
    if np.all(np.isnan(low)):
        return
    band = axes.fill_between(x, low, high, color=band_colour, alpha=_BAND_ALPHA, linewidth=0)
    band.set_gid(BAND_GID.format(name=name))


def build_latency_band_figure(bands: pd.DataFrame, series: SeedSeries,
                              average_target_s: float = math.nan) -> Figure:
    """Per method, latency percentiles as the mean over seeds with a 95% band.

    Args:
        bands: from :func:`latency_bands`.
        series: the runs' description (titles, footer).
        average_target_s: SafeTail's mean target latency over seeds, drawn dashed (NaN: none).

    Returns:
        The figure: one panel per baseline family present (each with SafeTail, Oracle and
        users' own methods), or a single panel when the runs have no baseline.
    """
    present = list(dict.fromkeys(bands["method"]))
    references = [m for m in (results.SAFETAIL, results.ORACLE) if m in present]
    references += own_methods(present)
    families = [f for f in results.BASELINE_FAMILIES if results.baselines_of(present, f)]
    panels = [(f"SafeTail vs {family}-x", [*references, *results.baselines_of(present, family)])
              for family in families] or [("SafeTail and Oracle", references)]
    figure, all_axes = _new_figure(series, "Latency percentiles, test phase, mean over seeds",
                                   len(panels))
    positions = np.arange(len(results.PERCENTILES), dtype=float)
    for axes, (title, methods) in zip(all_axes, panels, strict=True):
        axes.set_title(title)
        for method in methods:
            part = bands[bands["method"] == method].sort_values("percentile")
            line_colour = colour(method, own_methods(present))
            axes.plot(positions, part["mean_s"].to_numpy(float), marker="o", markersize=3,
                      linewidth=1.2, color=line_colour, label=method)
            _band(axes, positions, part["ci_low_s"].to_numpy(float),
                  part["ci_high_s"].to_numpy(float), line_colour, method)
        if not math.isnan(average_target_s):
            axes.axhline(average_target_s, color="black", linestyle="--", linewidth=1,
                         label="average target")
        axes.set_xticks(positions, [PERCENTILE_NAMES[p] for p in results.PERCENTILES])
        axes.legend(loc="upper left", ncols=2)
    all_axes[0].set_ylabel("latency (s)")
    return figure


def build_servers_band_figure(bands: pd.DataFrame, series: SeedSeries,
                              boundary: float = math.nan) -> Figure:
    """SafeTail's servers per request (β-step means) over training and test, mean over seeds
    with a 95% band.

    Args:
        bands: from :func:`servers_bands`.
        series: the runs' description.
        boundary: the average episode number where training ends (dotted; NaN: none).
    """
    figure, (axes,) = _new_figure(series, "SafeTail servers per request, mean over seeds")
    for phase in results.PHASES:
        part = bands[bands["phase"] == phase]
        if part.empty:
            continue
        x = part["avg_episode"].to_numpy(float)
        line_colour = PHASE_COLOURS[phase]
        axes.plot(x, part["mean"].to_numpy(float), marker="o", markersize=2.5, linewidth=1.2,
                  color=line_colour, label=f"{phase}ing")
        _band(axes, x, part["ci_low"].to_numpy(float), part["ci_high"].to_numpy(float),
              line_colour, phase)
    if not math.isnan(boundary):
        axes.axvline(boundary, color="#555555", linestyle=":", linewidth=1)
    # A request uses between 1 and n servers: the axis shows that whole range.
    axes.set_ylim(0.5, series.n_servers + 0.5)
    axes.set_xlabel(f"average episode number (steps / β, β = {series.beta})")
    axes.set_ylabel("servers per request (mean over β steps)")
    axes.legend(loc="best")
    return figure


def load_series(folders: Sequence[str | os.PathLike[str]]) -> tuple[SeedSeries, list[pd.DataFrame]]:
    """Read the runs' metadata and requests tables; check they are one use case and preset.

    Raises:
        ResultsFileError: a folder or file is missing or bad, or the runs mix use cases or
            presets.
    """
    if not folders:
        raise ValueError("no run folders given")
    paths = [Path(f) for f in folders]
    runs = [results.read_run_json(p) for p in paths]
    for path, run in zip(paths, runs, strict=True):
        if (run.use_case, run.preset) != (runs[0].use_case, runs[0].preset):
            raise ResultsFileError(
                f"{path / results.RUN_FILE}: keys use_case/preset: {run.use_case}/{run.preset} "
                f"differs from {runs[0].use_case}/{runs[0].preset} of {paths[0]}")
    series = SeedSeries(use_case=runs[0].use_case, use_case_name=runs[0].use_case_name,
                        preset=runs[0].preset, seeds=tuple(r.seed for r in runs),
                        beta=runs[0].beta, n_servers=runs[0].n_servers,
                        package_version=runs[0].package_version)
    return series, [results.read_requests_csv(p) for p in paths]


def _build(folders: Sequence[str | os.PathLike[str]]) -> tuple[SeedSeries, dict[str, Figure]]:
    series, requests = load_series(folders)
    stats = results.aggregate_summaries(folders)
    target = stats[(stats["method"] == results.SAFETAIL) & (stats["metric"] == "mean_target_s")]
    average_target_s = float(target["mean"].iloc[0]) if not target.empty else math.nan
    boundaries = {results.train_test_boundary(r, series.beta) for r in requests}
    # Seeds of one reproduction train for the same number of steps; if not, no single line.
    boundary = boundaries.pop() if len(boundaries) == 1 else math.nan
    with matplotlib.rc_context(STYLE):
        return series, {
            "latency": build_latency_band_figure(latency_bands(stats), series, average_target_s),
            "servers": build_servers_band_figure(servers_bands(requests, series.beta), series,
                                                 boundary),
        }


def draw_multiseed_figures(folders: Sequence[str | os.PathLike[str]],
                           out_dir: str | os.PathLike[str],
                           formats: Sequence[str] = DEFAULT_FIGURE_FORMATS) -> list[Path]:
    """Draw both figures into ``out_dir`` in each of ``formats`` (defaults.FIGURE_FORMATS).

    Args:
        folders: run folders of one use case and preset, one per seed.
        out_dir: created if missing.

    Returns:
        The written files: latency PNG, PDF, then servers PNG, PDF.

    Raises:
        ResultsFileError: a folder or file is missing or bad, or the runs mix use cases or
            presets (nothing is written then).
    """
    series, built = _build(folders)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stems = {"latency": LATENCY_BANDS_STEM, "servers": SERVERS_BANDS_STEM}
    written: list[Path] = []
    with matplotlib.rc_context(STYLE):
        for key, figure in built.items():
            written += save_figure(figure, out, stems[key].format(use_case=series.use_case,
                                                            preset=series.preset), formats)
    return written
