"""Run a use case, read its results and plot them from Python, in a few stable calls.

The command line (``yafs-safetail run``) and this module run the same experiment
(``runs.experiment.run_experiment``) and write the same results folder; this module is the
entry for notebooks and scripts::

    from yafs_safetail import api

    folder = api.run(1, steps_scale=0.02, seed=0)          # UC1 at 2% of the paper's budget
    results = api.read_results(folder)                     # summary, requests, run.json
    results.summary[["method", "p50_s", "p99_s"]]
    api.paper_figures(results)["a"]                        # the paper's panel (a)
    api.latency_cdf(results)                               # every method's latency CDF

Every function raises a ``ValueError`` subclass with one line naming the setting, file or
field and what is wrong; nothing is written before a run's checks pass, and a run replaces
only an earlier results folder, and that only with ``overwrite=True``. Importing this module
loads nothing heavy (NumPy, pandas, matplotlib and TensorFlow load on the first call that needs
them), so ``from yafs_safetail import api`` answers at once. docs/python_api.md documents it.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from yafs_safetail.defaults import default_placement
from yafs_safetail.settings.declare import check_config
from yafs_safetail.settings.experiment import ExperimentConfig

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from yafs_safetail.methods.policy import Policy
    from yafs_safetail.methods.registry import UserMethod
    from yafs_safetail.results.run_json import RunMetadata

__all__ = ["ApiError", "RunResults", "run", "read_results", "paper_figures", "latency_cdf",
           "compare_over_seeds", "SETTINGS"]


class ApiError(ValueError):
    """A bad argument to a function of this module (one line naming it and what is wrong)."""


#: Fields :func:`run` does not take as settings: its own arguments (``use_case``, ``out_dir``,
#: ``methods``), and what it sets itself (the call it records as the command; a campaign's id).
_SET_BY_RUN = ("command", "run_id", "methods", "out_dir", "use_case")
#: Every keyword :func:`run` takes besides ``use_case``, ``out_dir`` and ``methods``: the fields of
#: ``settings.experiment.ExperimentConfig`` (docs/usage.md lists them as options).
SETTINGS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(ExperimentConfig)
                                  if f.name not in _SET_BY_RUN)


# ----------------------------------------------------------------------------- running


def _user_method(method: str | type[Policy] | UserMethod) -> UserMethod:
    """A ``methods`` entry as the run takes it: a ``[NAME=]file.py:Class`` or ``module:Class``
    spec, an already parsed ``UserMethod``, or a ``Policy`` subclass defined at the top level of
    a module (a notebook's cells are the module ``__main__``)."""
    from yafs_safetail.methods.policy import Policy
    from yafs_safetail.methods.registry import UserMethod

    if isinstance(method, UserMethod):
        return method
    if isinstance(method, str):
        return UserMethod(method)
    if isinstance(method, type) and issubclass(method, Policy):
        module = sys.modules.get(method.__module__)
        # The run finds the class again by its module and name (forked workers build their own
        # instances, and run.json records the spec), so it must be reachable that way.
        if getattr(module, method.__name__, None) is not method:
            raise ApiError(f"run(): methods: {method.__qualname__} is not reachable as "
                           f"{method.__module__}.{method.__name__}; define it at the top level of a "
                           "module or notebook cell")
        return UserMethod(f"{method.__module__}:{method.__name__}")
    raise ApiError(f"run(): methods: {method!r} is neither 'file.py:Class', 'module:Class' nor a "
                   "Policy subclass")


def _default_out_dir(config: ExperimentConfig) -> Path:
    """The command's default folder (``results/uc<N>-<preset>-s<seed>...``), relative to the
    working folder, so a run from Python lands where the same command's would."""
    from yafs_safetail.commands.run_usecase import default_out_dir

    return default_out_dir(argparse.Namespace(
        use_case=config.use_case, preset=config.preset, seed=config.seed,
        steps_scale=config.steps_scale, learning_rate=config.learning_rate,
        topology=config.topology))


def _call_text(use_case: int, out_dir: Path, methods: Sequence[UserMethod],
               settings: dict[str, Any]) -> str:
    """The call as run.json records it, in place of a command line."""
    parts = [repr(use_case), f"out_dir={str(out_dir)!r}"]
    if methods:
        parts.append(f"methods={[m.spec for m in methods]!r}")
    parts += [f"{name}={value!r}" for name, value in settings.items()]
    return f"yafs_safetail.api.run({', '.join(parts)})"


def run(use_case: int = 1, *, out_dir: str | os.PathLike[str] | None = None,
        methods: Iterable[str | type[Policy] | UserMethod] = (), **settings: Any) -> Path:
    """Train SafeTail on one use case, test it and every other method, write the results folder.

    The same run as ``yafs-safetail run --uc USE_CASE ...`` (identical results files for the
    same settings, apart from the command ``run.json`` records). Progress bars are off unless
    ``progress=True``; the run logs its phases through :mod:`logging` (logger ``yafs_safetail``).

    Args:
        use_case: 1 object detection, 2 instance segmentation, 3 noise removal.
        out_dir: the results folder (default: the command's, ``results/uc<N>-<preset>-s<seed>``
            plus ``-x<scale>`` with ``steps_scale``, relative to the working folder). Written only
            when the run succeeds; an earlier results folder there is replaced only with
            ``overwrite=True``.
        methods: your own policies beside the built-in ones: ``Policy`` subclasses (defined at the
            top level of a module or notebook), ``"file.py:Class"`` or ``"module:Class"`` specs
            (``"NAME=file.py:Class"`` names it in the results).
        **settings: any of :data:`SETTINGS` (``settings.experiment.ExperimentConfig``'s fields:
            ``seed``, ``preset``, ``steps_scale``, ``redundancy_levels``, ``topology``,
            ``figures``, ``workers``, ``overwrite``, ``target_latency_s``...), checked as the
            command checks its options. ``placement`` defaults to the topology's.

    Returns:
        The results folder (see :func:`read_results`).

    Raises:
        ValueError: an unknown or bad setting, a bad input file or policy (one line naming it);
            nothing is written then.
        OSError: the folder cannot be written.
    """
    unknown = sorted(set(settings) - set(SETTINGS))
    if unknown:
        raise ApiError(f"run(): {unknown[0]!r} is not a setting; the settings are "
                       f"{', '.join(SETTINGS)}")
    values = dict(settings)
    for name in ("topology", "placement", "traces_dir", "policy", "down_intervals"):
        if values.get(name) is not None:
            values[name] = Path(values[name])
    if isinstance(values.get("redundancy_levels"), list | range):  # anything else: the check says
        values["redundancy_levels"] = tuple(values["redundancy_levels"])
    if "placement" not in values and "topology" in values:
        values["placement"] = default_placement(values["topology"])
        if not values["placement"].is_file() and values["topology"].is_file():
            # The loader would name a file the caller never gave: say where it came from.
            raise ApiError(f"run(): placement: {values['placement']} not found, the default for "
                           f"topology {values['topology']}; pass placement=")
    values.setdefault("progress", False)  # a notebook's stderr shows bars as a wall of lines
    user_methods = tuple(_user_method(m) for m in methods)
    config = ExperimentConfig(use_case=use_case, methods=user_methods, **values)
    check_config(config, style="field")  # errors name the keyword, not the command's option
    folder = Path(out_dir) if out_dir is not None else _default_out_dir(config)
    config = dataclasses.replace(config, out_dir=folder,
                                 command=_call_text(use_case, folder, user_methods, settings))
    # TensorFlow's C++ start-up notes say nothing about the run (as run_cli); an explicit
    # TF_CPP_MIN_LOG_LEVEL in the environment still wins.
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    from yafs_safetail.runs.experiment import run_experiment  # NumPy, simpy, maybe TensorFlow

    return run_experiment(config).out_dir


# ----------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class RunResults:
    """One results folder, read and checked.

    Attributes:
        folder: the results folder.
        summary: ``summary.csv``: one row per method (test phase): ``p50_s``, ``p90_s``,
            ``p95_s``, ``p99_s``, ``mean_s``, ``mean_access_rate``, ``target_met_rate``...
            (docs/results.md lists every column).
        requests: ``requests.csv``: one row per request, method and phase (``latency_s``,
            ``target_s``, ``servers``, ``reward``...).
        run: ``run.json``: use case, preset, seed, β, steps, methods, the world's settings.
    """

    folder: Path
    summary: pd.DataFrame
    requests: pd.DataFrame
    run: RunMetadata

    @property
    def test_requests(self) -> pd.DataFrame:
        """The test phase's rows, the ones every method is compared on (same requests)."""
        return self.requests[self.requests["phase"] == "test"]


def read_results(folder: str | os.PathLike[str]) -> RunResults:
    """Read a results folder written by :func:`run` or ``yafs-safetail run``.

    Raises:
        ValueError: the folder, ``summary.csv``, ``requests.csv`` or ``run.json`` is missing or
            bad (one line naming the file and the field).
    """
    from yafs_safetail import results

    path = Path(folder)
    if not path.is_dir():
        raise results.ResultsFileError(f"{path}: results folder not found")
    return RunResults(folder=path, summary=results.read_summary_csv(path),
                      requests=results.read_requests_csv(path), run=results.read_run_json(path))


def _as_results(results: RunResults | str | os.PathLike[str]) -> RunResults:
    return results if isinstance(results, RunResults) else read_results(results)


# ----------------------------------------------------------------------------- plotting


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

    loaded = _as_results(results)
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
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from yafs_safetail.results import PHASES, SAFETAIL, sort_methods

    if phase not in PHASES:
        raise ApiError(f"latency_cdf(): phase {phase!r}: expected one of {', '.join(PHASES)}")
    loaded = _as_results(results)
    rows = loaded.requests[loaded.requests["phase"] == phase]
    present = sort_methods(rows["method"])
    chosen = present if methods is None else list(methods)
    missing = [m for m in chosen if m not in present]
    if missing or not chosen:
        raise ApiError(f"latency_cdf(): methods: {missing[0] if missing else 'none given'!r} has no "
                       f"{phase} rows in {loaded.folder}; it has {', '.join(present) or 'none'}")
    figure = Figure(figsize=(5.2, 3.5))
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    for method in chosen:
        latency_s = np.sort(rows.loc[rows["method"] == method, "latency_s"].to_numpy(dtype=float))
        share = np.arange(1, latency_s.size + 1) / latency_s.size
        # SafeTail on top: at small budgets it often coincides with Oracle, which would hide it.
        on_top = method == SAFETAIL
        (line,) = axes.step(latency_s, share, where="post", linewidth=1.6 if on_top else 1.1,
                            zorder=3 if on_top else 2, label=method)
        p99_s = float(np.percentile(latency_s, 99))
        axes.plot([p99_s], [0.99], marker="o", markersize=3, color=line.get_color())
    axes.axhline(0.99, color="#777777", linestyle=":", linewidth=0.8)
    axes.set_xlabel("latency (s)")
    axes.set_ylabel("fraction of requests answered")
    axes.set_ylim(0, 1.02)
    axes.grid(alpha=0.3)
    axes.legend(fontsize=7, frameon=False, loc="lower right")
    run_meta = loaded.run
    axes.set_title(f"Latency CDF ({phase}), use case {run_meta.use_case}, preset {run_meta.preset}, "
                   f"seed {run_meta.seed}; dot: p99", fontsize=9)
    figure.tight_layout()
    return figure


# ----------------------------------------------------------------------------- across seeds


#: The summary columns :func:`compare_over_seeds` reports by default.
COMPARED_METRICS: tuple[str, ...] = ("p50_s", "p95_s", "p99_s", "mean_access_rate")


def compare_over_seeds(folders: Sequence[str | os.PathLike[str]], methods: Sequence[str] | None = None,
                       metrics: Sequence[str] = COMPARED_METRICS) -> pd.DataFrame:
    """Methods compared over runs of one use case (one run per seed): the mean over seeds and
    its 95% percentile-bootstrap interval (``results.over_seeds.bootstrap_interval``).

    Args:
        folders: results folders of one use case, one per seed.
        methods: the methods to keep, in this order (default: every method, report order).
        metrics: summary columns (``results.over_seeds.AGGREGATE_METRICS``).

    Returns:
        One row per method: for each metric ``<metric>``, ``<metric>_low`` and
        ``<metric>_high``, then ``n_seeds`` (the runs that have the method).

    Raises:
        ValueError: no folders, bad results files, runs mixing use cases, or an unknown method
            or metric.
    """
    from yafs_safetail.results.over_seeds import AGGREGATE_METRICS, aggregate_summaries

    bad_metric = [m for m in metrics if m not in AGGREGATE_METRICS]
    if bad_metric or not metrics:
        raise ApiError(f"compare_over_seeds(): metrics: {bad_metric[0] if bad_metric else 'none given'!r}; "
                       f"expected some of {', '.join(AGGREGATE_METRICS)}")
    if not folders:
        raise ApiError("compare_over_seeds(): folders: none given")
    table = aggregate_summaries(folders)
    present = list(dict.fromkeys(table["method"]))
    chosen = present if methods is None else list(methods)
    missing = [m for m in chosen if m not in present]
    if missing:
        raise ApiError(f"compare_over_seeds(): methods: {missing[0]!r} is in none of the runs; they "
                       f"have {', '.join(present)}")
    import pandas as pd

    rows = []
    for method in chosen:
        part = table[table["method"] == method].set_index("metric")
        row: dict[str, Any] = {"method": method}
        for metric in metrics:
            row[metric] = part.at[metric, "mean"]
            row[f"{metric}_low"] = part.at[metric, "ci_low"]
            row[f"{metric}_high"] = part.at[metric, "ci_high"]
        row["n_seeds"] = int(part["n_seeds"].max())
        rows.append(row)
    return pd.DataFrame(rows)
