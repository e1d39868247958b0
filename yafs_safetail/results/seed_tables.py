"""Methods compared over seeds: latency percentiles and servers per request, and speed-ups over
SafeTail and Oracle, each ``mean [95% interval over seeds]``.

REPORT.md shows these tables for the users' own policies (``reproduce_all.py --method``,
results/reproduction.py); a campaign ends with the latency table of what it ran, one per
setting of the grid's axes other than the seed (:func:`write_campaign_latency`:
``OUT/latency.md`` and ``OUT/latency.csv``). The numbers come from ``results.stats``
(:func:`~yafs_safetail.results.over_seeds.metrics_over_seeds`,
:func:`~yafs_safetail.results.over_seeds.speedups_over_seeds`); this module only lays them out.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from yafs_safetail.methods.registry import (
    CONTENTION_BASELINES,
    ORACLE,
    SAFETAIL,
    parse_method,
    sort_methods,
)
from yafs_safetail.results.files import (
    PERCENTILES,
    SUMMARY_CSV_FILE,
    read_summary_csv,
    write_text_atomic,
)
from yafs_safetail.results.markdown import format_number, frame_markdown
from yafs_safetail.results.over_seeds import SEED_TABLE_METRICS, metrics_over_seeds
from yafs_safetail.results.paper import PERCENTILE_NAMES
from yafs_safetail.results.report import PAPER_SOURCE
from yafs_safetail.results.run_json import read_run_json

#: Over the latency table: what its cells are.
LATENCY_NOTE = ("Test phase; mean over seeds [95% bootstrap interval over seeds]; servers per "
                "request = the mean number of servers a request's copies went to.")
#: Over the speed-up table: what its cells are (as the paper's ratios are read).
SPEEDUP_NOTE = ("Speed-up of A over B = latency(B) / latency(A) (> 1: A faster), computed within "
                "each seed; geometric mean over seeds [95% t-interval on the log scale].")
#: The references users' policies are compared with.
REFERENCES: tuple[str, ...] = (SAFETAIL, ORACLE)
#: A campaign's latency table, beside its campaign.json.
LATENCY_MD_FILE = "latency.md"
LATENCY_CSV_FILE = "latency.csv"
#: The grid field that seeds runs: the tables aggregate over it, never group by it.
SEED_FIELD = "seed"


def user_methods(names: Iterable[str]) -> list[str]:
    """The methods among ``names`` that are none of the built-in ones (SafeTail, Oracle, the
    Rand/MinLoad/MinProp baselines, Hedge, Tied): the users' own policies, report order."""
    return [name for name in sort_methods(names)
            if name not in (SAFETAIL, ORACLE) and name not in CONTENTION_BASELINES
            and parse_method(name)[1] is None]


def _cell(mean: float, low: float, high: float, digits: int) -> str:
    """``mean [low, high]``; just ``mean`` without an interval (one seed), ``—`` when missing."""
    if math.isnan(mean):
        return "—"
    if math.isnan(low):
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


#: The latency table's columns after the method and its seeds, by metric.
_METRIC_HEADERS = {**{f"p{p}_s": f"{PERCENTILE_NAMES[p]} (s)" for p in PERCENTILES},
                   "mean_n_selected": "servers per request"}


def latency_table(stats: pd.DataFrame, digits: int = 3) -> pd.DataFrame:
    """The latency table as display strings, one row per method (markdown and LaTeX alike).

    Args:
        stats: from :func:`~yafs_safetail.results.over_seeds.metrics_over_seeds` with
            ``SEED_TABLE_METRICS``.
        digits: decimals shown (servers per request: two).

    Returns:
        Columns ``method, seeds, median (s), p90 (s), p95 (s), p99 (s), servers per request``.
    """
    rows = []
    for method in sort_methods(stats["method"]):
        part = stats[stats["method"] == method].set_index("metric")
        row = [method, str(int(part["n_seeds"].max()))]
        for metric in SEED_TABLE_METRICS:
            entry = part.loc[metric]
            row.append(_cell(entry["mean"], entry["ci_low"], entry["ci_high"],
                             2 if metric == "mean_n_selected" else digits))
        rows.append(row)
    return pd.DataFrame(rows, columns=["method", "seeds", *(_METRIC_HEADERS[m] for m in SEED_TABLE_METRICS)],
                        dtype=object)


def speedup_table(speedups: pd.DataFrame) -> pd.DataFrame:
    """Speed-ups as display strings, one row per (method, reference).

    Args:
        speedups: from :func:`~yafs_safetail.results.over_seeds.speedups_over_seeds`.

    Returns:
        Columns ``method, over, seeds, median, p90, p95, p99``.
    """
    rows = []
    for (method, reference), part in speedups.groupby(["method", "reference"], sort=False):
        by_percentile = part.set_index("percentile")
        rows.append([method, reference, str(int(part["n_seeds"].max())),
                     *(_cell(by_percentile.loc[p, "mean"], by_percentile.loc[p, "ci_low"],
                             by_percentile.loc[p, "ci_high"], 2) for p in PERCENTILES)])
    return pd.DataFrame(rows, columns=["method", "over", "seeds", *(PERCENTILE_NAMES[p] for p in PERCENTILES)],
                        dtype=object)


def markdown(note: str, table: pd.DataFrame) -> str:
    """A note, then a table of display strings, as markdown ending with a newline."""
    return "\n".join([note, "", *frame_markdown(table)]) + "\n"


# ----------------------------------------------------------------------------- campaigns


def _shown(value: Any) -> str:
    """An axis value as a group's title shows it (a file by its name, not its absolute path)."""
    if isinstance(value, str):
        return Path(value).name if "/" in value else value
    return json.dumps(value)


def grouping_axes(settings: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The fields that differ between a campaign's runs, the seed aside, in the grid's order.

    Args:
        settings: each run's settings (``RunSpec.settings``) by run name.
    """
    axes: list[str] = []
    for run in settings.values():
        for name in run:
            if name != SEED_FIELD and name not in axes:
                axes.append(name)
    canonical = [{name: json.dumps(run.get(name), sort_keys=True) for name in axes}
                 for run in settings.values()]
    return [name for name in axes if len({values[name] for values in canonical}) > 1]


def campaign_latency(out: Path, settings: Mapping[str, Mapping[str, Any]],
                     finished: Sequence[str]) -> tuple[str, pd.DataFrame] | None:
    """The latency table of a campaign's finished runs, one per setting of its axes other than
    the seed.

    Args:
        out: the campaign folder; run ``name`` is ``out/name``.
        settings: every run's settings by name (all of them: they say which fields are axes).
        finished: the names of the runs that finished (now or earlier); a run folder without
            ``summary.csv`` (a point of a contention sweep) is left out.

    Returns:
        ``(markdown, frame)``, the frame one row per group and method (the axes' values,
        ``method``, ``n_seeds``, then per metric its mean, ``_low`` and ``_high``); None when
        no finished run has a ``summary.csv``.
    """
    axes = grouping_axes(settings)
    groups: dict[str, list[str]] = {}
    for name in finished:
        if (out / name / SUMMARY_CSV_FILE).is_file():
            key = json.dumps([settings[name].get(axis) for axis in axes])
            groups.setdefault(key, []).append(name)
    if not groups:
        return None
    by = ", ".join(axes) if axes else "nothing (every run shares its settings but the seed)"
    lines = ["# Latency over seeds", "", LATENCY_NOTE + f" One table per value of the grid's axes "
             f"other than the seed: {by}; {sum(map(len, groups.values()))} finished run(s).", ""]
    frames = []
    for names in groups.values():
        values = {axis: settings[names[0]].get(axis) for axis in axes}
        # From run.json: a grid that does not set the seed ran the default one.
        seeds = ", ".join(str(read_run_json(out / n).seed) for n in names)
        stats = metrics_over_seeds([read_summary_csv(out / n) for n in names])
        title = ", ".join(f"{axis}={_shown(value)}" for axis, value in values.items()) or "all runs"
        lines += [f"## {title} (seeds {seeds})", "", *frame_markdown(latency_table(stats)), ""]
        wide = stats.pivot(index="method", columns="metric", values=["mean", "ci_low", "ci_high"])
        frame = pd.DataFrame({"method": sort_methods(stats["method"])})
        frame["n_seeds"] = [int(stats.loc[stats["method"] == m, "n_seeds"].max()) for m in frame["method"]]
        for metric in SEED_TABLE_METRICS:
            for part, suffix in (("mean", ""), ("ci_low", "_low"), ("ci_high", "_high")):
                frame[metric + suffix] = [wide.loc[m, (part, metric)] for m in frame["method"]]
        for position, (axis, value) in enumerate(values.items()):
            frame.insert(position, axis, _shown(value))
        frames.append(frame)
    return "\n".join(lines), pd.concat(frames, ignore_index=True)


def write_campaign_latency(out: Path, settings: Mapping[str, Mapping[str, Any]],
                           finished: Sequence[str]) -> str:
    """Write ``out/latency.md`` and ``out/latency.csv`` (:func:`campaign_latency`) and return
    the markdown ("" and nothing written when no finished run has a ``summary.csv``)."""
    found = campaign_latency(Path(out), settings, finished)
    if found is None:
        return ""
    text, frame = found
    write_text_atomic(Path(out) / LATENCY_MD_FILE, text)
    write_text_atomic(Path(out) / LATENCY_CSV_FILE, frame.to_csv(index=False))
    return text


# ----------------------------------------------------------------------------- REPORT.md's tables over seeds

#: The note over the cross-seed latency table (REPORT.md and its LaTeX twin).
AGGREGATE_NOTE = "Test phase; mean over seeds [95% bootstrap interval over seeds]."
#: The note over the side-by-side ratio table (REPORT.md and its LaTeX twin).
COMPARISON_NOTE = (
    "Speed-up of A over B = latency(B) / latency(A) (> 1: A faster). \"ours\" = geometric mean over "
    "seeds [95% t-interval on the log scale]; \"paper\" = the paper's stated number in the same "
    f"direction ({PAPER_SOURCE})."
)


def _with_interval(mean: float, low: float, high: float, digits: int) -> str:
    cell = format_number(mean, digits)
    if not math.isnan(low):
        cell += f" [{low:.{digits}f}, {high:.{digits}f}]"
    return cell


def aggregate_table(stats: pd.DataFrame, digits: int = 3) -> pd.DataFrame:
    """The cross-seed latency table as display strings, one row per method.

    REPORT.md and the LaTeX tables are both made from this frame, so they show the same numbers.

    Args:
        stats: from :func:`aggregate_summaries`.
        digits: decimals shown.

    Returns:
        Columns ``method, seeds, median (s), p90 (s), p95 (s), p99 (s), mean access rate,
        mean target (s)``; each metric cell ``mean [low, high]`` (just ``mean`` without an
        interval, ``—`` when missing).
    """
    header = ["method", "seeds", *[PERCENTILE_NAMES[p] + " (s)" for p in PERCENTILES],
              "mean access rate", "mean target (s)"]
    metrics = [f"p{p}_s" for p in PERCENTILES] + ["mean_access_rate", "mean_target_s"]
    rows = []
    for method in sort_methods(stats["method"]):
        part = stats[stats["method"] == method].set_index("metric")
        row = [method, str(int(part["n_seeds"].max()))]
        for metric in metrics:
            row.append(_with_interval(part.loc[metric, "mean"], part.loc[metric, "ci_low"],
                                      part.loc[metric, "ci_high"], digits))
        rows.append(row)
    return pd.DataFrame(rows, columns=header, dtype=object)


def aggregate_markdown(stats: pd.DataFrame, digits: int = 3) -> str:
    """Markdown table of :func:`aggregate_summaries`: one row per method, ``mean [95% interval]``.

    Args:
        stats: from :func:`aggregate_summaries`.
        digits: decimals shown.

    Returns:
        Markdown text ending with a newline.
    """
    lines = [AGGREGATE_NOTE, "", *frame_markdown(aggregate_table(stats, digits))]
    return "\n".join(lines) + "\n"


def comparison_table(aggregated: pd.DataFrame, only_stated: bool = False) -> pd.DataFrame:
    """Our ratios (mean [95% interval]) beside the paper's, as display strings.

    Args:
        aggregated: from :func:`aggregate_speedups` (several use cases may be concatenated).
        only_stated: keep only the rows for which the paper states a number.

    Returns:
        Columns ``use case, comparison, percentile, ours, seeds, paper, differs?``.
    """
    rows = []
    for entry in aggregated.itertuples(index=False):
        if only_stated and math.isnan(entry.paper):
            continue
        rows.append([
            str(entry.use_case), f"{entry.method} over {entry.reference}",
            PERCENTILE_NAMES[int(entry.percentile)],
            _with_interval(entry.mean, entry.ci_low, entry.ci_high, 2), str(entry.n_seeds),
            format_number(entry.paper, 2), entry.note,
        ])
    return pd.DataFrame(rows, columns=["use case", "comparison", "percentile", "ours", "seeds",
                                       "paper", "differs?"], dtype=object)


def comparison_markdown(aggregated: pd.DataFrame, only_stated: bool = False) -> str:
    """Side-by-side markdown table of our ratios (mean [95% interval]) and the paper's.

    Args:
        aggregated: from :func:`aggregate_speedups` (several use cases may be concatenated).
        only_stated: keep only the rows for which the paper states a number.

    Returns:
        Markdown text ending with a newline.
    """
    lines = [COMPARISON_NOTE, "", *frame_markdown(comparison_table(aggregated, only_stated))]
    return "\n".join(lines) + "\n"
