"""The paper's Figs. 5-7, panels (a)-(g), drawn from a results folder alone.

:func:`draw_figures` (``yafs-safetail figures RESULTS_DIR`` runs it) reads ``requests.csv`` and
``run.json`` (see ``docs/results.md``) and writes, into ``RESULTS_DIR/figures/``, one file per
panel in each format asked (PNG by default, PDF too):

* (a) ``fig_a_latency_comparison``: median/p90/p95/p99 of SafeTail, Oracle and the x = 1
  baselines, with the average target latency marked;
* (b)-(d) ``fig_b_safetail_vs_rand``, ``fig_c_safetail_vs_minload``,
  ``fig_d_safetail_vs_minprop``: SafeTail against every x of that baseline in the run;
* (e)-(g) ``fig_e_access_rate``, ``fig_f_latency_deviation``, ``fig_g_abs_reward``: SafeTail's
  β-step averages per average episode, training then testing, the boundary marked;
* beyond the paper, ``p99_vs_energy`` (each method's p99 against its energy per request) and
  ``latency_cdf`` (each method's test-phase latency CDF on a log axis, the average target marked).

Each figure is one function registered with :func:`run_figure` (:data:`RUN_FIGURES`, in drawing
order): a new figure of every run is one more. Latency panels use the test phase. Figures are drawn with matplotlib's object API on the Agg
canvas (no pyplot, so no global figure state and nothing to close), and every file is written
under a temporary name and renamed, so bad input or a crash never leaves a half-written or
deleted figure behind.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from yafs_safetail import results
from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS
from yafs_safetail.results import ResultsFileError, RunMetadata
from yafs_safetail.results.figures.style import (
    PHASE_COLOURS,
    STYLE,
    colour,
    own_methods,
    save_figure,
)
from yafs_safetail.results.paper import PERCENTILE_NAMES

FIGURES_DIR = "figures"


@dataclass(frozen=True)
class FigureInputs:
    """What every figure of a run is drawn from: the checked requests table, its summary per
    method (test phase), the train/test boundary in average episodes, and the run's metadata."""

    requests: pd.DataFrame
    summary: pd.DataFrame
    boundary: float
    run: RunMetadata


#: Each figure of a run, in drawing order: its key (a panel letter, or a name beyond the paper)
#: -> the function that builds it. A new figure is one function under :func:`run_figure`.
RUN_FIGURES: dict[str, Callable[[FigureInputs], Figure]] = {}
#: Each figure's key -> its file's name without the extension (in ``RESULTS_DIR/figures/``).
FIGURE_STEMS: dict[str, str] = {}


def run_figure(key: str, stem: str) -> Callable[[Callable[[FigureInputs], Figure]], Callable[[FigureInputs], Figure]]:
    """Register a figure of every run: ``build(inputs) -> Figure``, drawn under matplotlib's
    style and written as ``figures/<stem>.<format>`` by :func:`draw_figures` (and by each run)."""
    def register(build: Callable[[FigureInputs], Figure]) -> Callable[[FigureInputs], Figure]:
        if key in RUN_FIGURES or stem in FIGURE_STEMS.values():
            raise ValueError(f"run_figure: the figure {key!r} or the file {stem!r} is taken")
        RUN_FIGURES[key] = build
        FIGURE_STEMS[key] = stem
        return build
    return register


_FIGSIZE_IN = (5.2, 3.5)


def _new_figure(run: RunMetadata, title: str) -> tuple[Figure, Axes]:
    # Fixed margins rather than a layout engine: constrained layout measures every text
    # artist on each save and roughly doubles the drawing time.
    figure = Figure(figsize=_FIGSIZE_IN)
    figure.subplots_adjust(left=0.12, right=0.97, bottom=0.17, top=0.85)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    axes.set_title(f"{title}\nuse case {run.use_case}, preset {run.preset}{run.learning_rate_note}"
                   f"{run.settings_note}")
    # The long use-case name goes in the footer, where it cannot run off the figure's edge.
    reading = f"; baselines: {run.baseline_reading}" if run.baseline_reading else ""
    figure.text(0.99, 0.005, f"{run.use_case_name}; seed {run.seed}, β = {run.beta}{reading}, "
                f"yafs-safetail {run.package_version}",
                ha="right", va="bottom", fontsize=6, color="#777777", wrap=True)
    return figure, axes


def _percentile_bars(axes: Axes, summary: pd.DataFrame, methods: Sequence[str]) -> None:
    n_methods = max(len(methods), 1)
    width = 0.8 / n_methods
    positions = np.arange(len(results.PERCENTILES))
    own = own_methods(list(summary["method"]))
    for i, method in enumerate(methods):
        row = summary[summary["method"] == method].iloc[0]
        heights = [float(row[f"p{p}_s"]) for p in results.PERCENTILES]
        axes.bar(positions + (i - (n_methods - 1) / 2) * width, heights, width * 0.95,
                 label=method, color=colour(method, own))
    axes.set_xticks(positions, [PERCENTILE_NAMES[p] for p in results.PERCENTILES])
    axes.set_ylabel("latency (s)")


def _average_target_s(requests: pd.DataFrame) -> float:
    test = requests[requests["phase"] == "test"]
    safetail = test[test["method"] == results.SAFETAIL]
    return float((safetail if not safetail.empty else test)["target_s"].mean())


def _latency_comparison(requests: pd.DataFrame, summary: pd.DataFrame,
                        run: RunMetadata) -> Figure:
    present = list(summary["method"])
    methods = [m for m in (results.SAFETAIL, results.ORACLE) if m in present]
    methods += [b for b in results.baselines_of(present) if results.parse_method(b)[1] == 1]
    own = own_methods(present)
    methods += own
    title = "(a) Latency: SafeTail, Oracle, x = 1 baselines" + (", your methods" if own else "")
    figure, axes = _new_figure(run, title)
    _percentile_bars(axes, summary, methods)
    axes.axhline(_average_target_s(requests), color="black", linestyle="--", linewidth=1,
                 label="average target")
    axes.legend(ncols=3, loc="upper left")
    axes.margins(y=0.25)
    return figure


def _family_comparison(summary: pd.DataFrame, run: RunMetadata, panel: str,
                       family: str) -> Figure:
    present = list(summary["method"])
    levels = results.baselines_of(present, family)
    title = f"({panel}) SafeTail vs {family}-x"
    if not levels:
        title += f" (no {family}-x in this run)"
    figure, axes = _new_figure(run, title)
    _percentile_bars(axes, summary, [results.SAFETAIL, *levels])
    axes.legend(ncols=4, loc="upper left")
    axes.margins(y=0.2)
    return figure


def _episode_curve(curve: pd.DataFrame, boundary: float, run: RunMetadata, panel: str,
                   title: str, ylabel: str, zero_line: bool = False) -> Figure:
    figure, axes = _new_figure(run, f"({panel}) {title}")
    if zero_line:
        axes.axhline(0.0, color="black", linewidth=0.8)
    for phase in results.PHASES:
        part = curve[curve["phase"] == phase]
        if not part.empty:
            axes.plot(part["avg_episode"], part["value"], marker="o", markersize=2.5,
                      linewidth=1.2, color=PHASE_COLOURS[phase], label=f"{phase}ing")
    if (curve["phase"] == "test").any() and (curve["phase"] == "train").any():
        axes.axvline(boundary, color="#555555", linestyle=":", linewidth=1)
    axes.set_xlabel(f"average episode number (steps / β, β = {run.beta})")
    axes.set_ylabel(ylabel)
    axes.legend(loc="best")
    return figure


def _p99_against_energy(summary: pd.DataFrame, run: RunMetadata) -> Figure:
    """Each method's p99 latency against its mean energy per request (test phase)."""
    figure, axes = _new_figure(run, "p99 latency against energy per request")
    present = list(summary["method"])
    own = own_methods(present)
    energy = summary["energy_j_per_request"].to_numpy(dtype=float)
    if not np.isfinite(energy).any():
        axes.set_title(axes.get_title() + "\n(no energy columns: written before them)", fontsize=7)
    for method, energy_j, p99_s in zip(present, energy, summary["p99_s"], strict=True):
        if np.isfinite(energy_j):
            axes.scatter(energy_j, p99_s, s=22, color=colour(method, own), label=method, zorder=3)
            axes.annotate(method, (energy_j, p99_s), textcoords="offset points", xytext=(3, 3), fontsize=6)
    axes.set_xlabel("energy per request (J): servers' copies + the device's radio")
    axes.set_ylabel("p99 latency (s)")
    axes.margins(0.15)
    return figure


def latency_cdf(requests: pd.DataFrame, run: RunMetadata, methods: Sequence[str], phase: str = "test",
                *, panel: bool = True) -> Figure:
    """Each of ``methods``' empirical CDF of its latencies in ``phase``, on one axes: the one
    drawing of it, in two looks. Where the bars of (a)-(d) show four percentiles, this shows all
    of them, so a tail that a percentile steps over (fallbacks, a second mode) is seen.

    Args:
        requests: a requests table (every phase; a method without rows in ``phase`` is skipped).
        run: the run's metadata.
        methods: the methods to draw, in this order.
        phase: ``"test"`` or ``"train"``.
        panel: True, the run's ``latency_cdf`` figure (drawn under ``STYLE``): log-x, each
            method in its family's colour, the average target marked; False, the API's
            (``api.latency_cdf``): linear x, matplotlib's colours, each method's p99 dotted.
    """
    if panel:
        figure, axes = _new_figure(run, "Latency CDF, test phase")
    else:
        figure = Figure(figsize=_FIGSIZE_IN)
        FigureCanvasAgg(figure)
        axes = figure.add_subplot()
    rows = requests[requests["phase"] == phase]
    own = own_methods(list(methods))
    for method in methods:
        latencies_s = np.sort(rows.loc[rows["method"] == method, "latency_s"].to_numpy(dtype=float))
        if latencies_s.size == 0:
            continue
        share = np.arange(1, latencies_s.size + 1) / latencies_s.size
        if not panel:
            # SafeTail on top: at small budgets it often coincides with Oracle, which would hide it.
            on_top = method == results.SAFETAIL
            (line,) = axes.step(latencies_s, share, where="post", linewidth=1.6 if on_top else 1.1,
                                zorder=3 if on_top else 2, label=method)
            axes.plot([float(np.percentile(latencies_s, 99))], [0.99], marker="o", markersize=3,
                      color=line.get_color())
            continue
        family, level = results.parse_method(method)
        # The learner and the bound stand out; the baselines' levels are told apart by dashes too,
        # since their shades of one colour are close.
        emphasis = method in (results.SAFETAIL, results.ORACLE) or method in own
        style = "-" if emphasis or level in (None, 1) else ("--" if level == 2 else ":")
        # SafeTail on top: it often runs along Oracle's curve and would be hidden under it.
        layer = 4 if method == results.SAFETAIL else 3 if emphasis else 2
        axes.step(latencies_s, share, where="post", color=colour(method, own), label=method,
                  linestyle=style, linewidth=1.8 if emphasis else 1.0, zorder=layer)
    if panel:
        _panel_cdf_axes(figure, axes, requests)
    else:
        _plain_cdf_axes(figure, axes, run, phase)
    return figure


def _panel_cdf_axes(figure: Figure, axes: Axes, requests: pd.DataFrame) -> None:
    """The run's CDF figure: the average target, a log-x axis, the legend beside the axes."""
    target_s = _average_target_s(requests)
    axes.axvline(target_s, color="black", linestyle="--", linewidth=1,
                 label=f"avg. target {target_s:.2g} s")
    # Latencies span a factor of ten or more between Oracle's median and a baseline's fallbacks:
    # a log axis keeps both the body and the tail readable.
    axes.set_xscale("log")
    # Plain numbers (0.5, 2, not 5×10⁻¹, 2×10⁰), and between two powers of ten only 2, 3 and 5:
    # every minor tick labelled would run together.
    axes.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axes.xaxis.set_minor_formatter(FuncFormatter(
        lambda value, _: f"{value:g}" if f"{value:.0e}"[0] in "235" else ""))
    axes.tick_params(axis="x", which="both", labelsize=7)
    axes.set_xlabel("latency (s), log scale")
    axes.set_ylabel("share of test requests ≤ latency")
    axes.set_ylim(0.0, 1.02)
    # Beside the axes: inside, eleven entries would cover the curves wherever they were put.
    figure.subplots_adjust(right=0.73)
    axes.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=6.5, borderaxespad=0)


def _plain_cdf_axes(figure: Figure, axes: Axes, run: RunMetadata, phase: str) -> None:
    """The API's CDF figure: the p99 line, a linear axis, the legend inside, a one-line title."""
    axes.axhline(0.99, color="#777777", linestyle=":", linewidth=0.8)
    axes.set_xlabel("latency (s)")
    axes.set_ylabel("fraction of requests answered")
    axes.set_ylim(0, 1.02)
    axes.grid(alpha=0.3)
    axes.legend(fontsize=7, frameon=False, loc="lower right")
    axes.set_title(f"Latency CDF ({phase}), use case {run.use_case}, preset {run.preset}, "
                   f"seed {run.seed}; dot: p99", fontsize=9)
    figure.tight_layout()


def read_figure_inputs(directory: str | os.PathLike[str]) -> tuple[pd.DataFrame, RunMetadata]:
    """Read and check what the figures need from a results folder.

    Raises:
        ResultsFileError: the folder, ``requests.csv`` or ``run.json`` is missing or bad, or
            ``requests.csv`` has no SafeTail rows or no test rows.
    """
    folder = Path(directory)
    if not folder.is_dir():
        raise ResultsFileError(f"{folder}: results folder not found")
    requests = results.read_requests_csv(folder)
    run = results.read_run_json(folder)
    file = folder / results.REQUESTS_FILE
    if not (requests["method"] == results.SAFETAIL).any():
        raise ResultsFileError(f"{file}: column method: no {results.SAFETAIL} rows")
    if not (requests["phase"] == "test").any():
        raise ResultsFileError(f"{file}: column phase: no test rows")
    return requests, run


@run_figure("a", "fig_a_latency_comparison")
def _figure_a(inputs: FigureInputs) -> Figure:
    return _latency_comparison(inputs.requests, inputs.summary, inputs.run)


def _family_figure(panel: str, family: str) -> Callable[[FigureInputs], Figure]:
    def build(inputs: FigureInputs) -> Figure:
        return _family_comparison(inputs.summary, inputs.run, panel, family)
    return build


for _panel, _family, _stem in zip("bcd", results.BASELINE_FAMILIES,
                                  ("fig_b_safetail_vs_rand", "fig_c_safetail_vs_minload", "fig_d_safetail_vs_minprop"),
                                  strict=True):
    run_figure(_panel, _stem)(_family_figure(_panel, _family))


@run_figure("e", "fig_e_access_rate")
def _figure_e(inputs: FigureInputs) -> Figure:
    return _episode_curve(results.access_rate_by_episode(inputs.requests, inputs.run.beta), inputs.boundary,
                          inputs.run, "e", "SafeTail access rate", "average access rate")


@run_figure("f", "fig_f_latency_deviation")
def _figure_f(inputs: FigureInputs) -> Figure:
    return _episode_curve(results.latency_deviation_by_episode(inputs.requests, inputs.run.beta), inputs.boundary,
                          inputs.run, "f", "SafeTail latency deviation", "average target − latency (s)",
                          zero_line=True)


@run_figure("g", "fig_g_abs_reward")
def _figure_g(inputs: FigureInputs) -> Figure:
    return _episode_curve(results.abs_reward_by_episode(inputs.requests, inputs.run.beta), inputs.boundary,
                          inputs.run, "g", "SafeTail |reward|", "average |reward|")


# Beyond the paper: what each method's tail costs in energy (docs/failures_energy.md).
@run_figure("energy", "p99_vs_energy")
def _figure_energy(inputs: FigureInputs) -> Figure:
    return _p99_against_energy(inputs.summary, inputs.run)


# Beyond the paper: every method's whole test-phase latency distribution, not four points of it.
@run_figure("cdf", "latency_cdf")
def _figure_cdf(inputs: FigureInputs) -> Figure:
    return latency_cdf(inputs.requests, inputs.run, list(inputs.summary["method"]))


def build_figures(requests: pd.DataFrame, run: RunMetadata) -> dict[str, Figure]:
    """Build every figure of :data:`RUN_FIGURES` in memory, without writing anything: panels
    (a)-(g), the p99-against-energy figure and the latency CDF (and any figure added since).

    Args:
        requests: a checked requests table (see :func:`read_figure_inputs`).
        run: the run's metadata.

    Returns:
        Each figure's key ("a".."g", "energy", "cdf", ...) to its matplotlib Figure (on an Agg
        canvas), in :data:`RUN_FIGURES` order.
    """
    summary = results.summarize(requests, preset=run.preset, beta=run.beta)
    inputs = FigureInputs(requests, summary, results.train_test_boundary(requests, run.beta), run)
    with matplotlib.rc_context(STYLE):
        return {key: build(inputs) for key, build in RUN_FIGURES.items()}


def draw_figures(
    directory: str | os.PathLike[str],
    requests: pd.DataFrame | None = None,
    run: RunMetadata | None = None,
    formats: Sequence[str] = DEFAULT_FIGURE_FORMATS,
) -> list[Path]:
    """Draw panels (a)-(g), ``p99_vs_energy`` and ``latency_cdf`` into ``directory/figures`` in
    each of ``formats``.

    Args:
        directory: the results folder.
        requests: the requests table (read from ``requests.csv`` when None).
        run: the run's metadata (read from ``run.json`` when None).
        formats: a subset of FIGURE_FORMATS (PDF takes about as long as PNG to write).

    Returns:
        The written files, panel by panel, in FIGURE_FORMATS order.

    Raises:
        ResultsFileError: bad or missing input (nothing is written or removed then).
    """
    folder = Path(directory)
    if requests is None or run is None:
        loaded_requests, loaded_run = read_figure_inputs(folder)
        requests = loaded_requests if requests is None else requests
        run = loaded_run if run is None else run
    built = build_figures(requests, run)
    out = folder / FIGURES_DIR
    out.mkdir(exist_ok=True)
    written: list[Path] = []
    with matplotlib.rc_context(STYLE):
        for panel, figure in built.items():
            written += save_figure(figure, out, FIGURE_STEMS[panel], formats)
    return written
