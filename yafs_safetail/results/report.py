"""Markdown reports of results: a run's ``summary.md``, cross-seed tables, and the writers that
put a run's files in its folder."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from yafs_safetail.methods.registry import ORACLE, SAFETAIL
from yafs_safetail.numerics import NUMERICS_KEY, not_pinned_note
from yafs_safetail.results.claims import check_claims
from yafs_safetail.results.files import (
    MIN_REQUESTS_BEYOND_PERCENTILE,
    PERCENTILES,
    RUN_FILE,
    SUMMARY_CSV_FILE,
    SUMMARY_MD_FILE,
    _csv_text,
    read_requests_csv,
    thin_percentiles,
    write_requests_csv,
    write_text_atomic,
)
from yafs_safetail.results.markdown import format_number, markdown_table
from yafs_safetail.results.paper import (
    PERCENTILE_NAMES,
    setting_differences,
    speedup_table,
)
from yafs_safetail.results.run_json import (
    RunMetadata,
    read_run_json,
    write_run_json,
)
from yafs_safetail.results.stats import summarize
from yafs_safetail.versions import NOT_THE_LOCK_KEY, not_the_lock_note

#: Where a reader finds the paper's stated numbers and how they are read, as results files
#: cite it: the paper itself and a file of the project (every reader has both).
PAPER_SOURCE = "Section V of the paper; see docs/results.md"

def _speedup_lines(table: pd.DataFrame, method: str, reference: str | None) -> list[str]:
    header = ["comparison"]
    for percentile in PERCENTILES:
        name = PERCENTILE_NAMES[percentile]
        header += [f"{name} ours", f"{name} paper"]
    rows = []
    pairs = table[["method", "reference"]].drop_duplicates().itertuples(index=False)
    for pair_method, pair_reference in pairs:
        if pair_method != method or (reference is not None and pair_reference != reference):
            continue
        part = table[(table["method"] == pair_method) & (table["reference"] == pair_reference)]
        row = [f"{pair_method} over {pair_reference}"]
        for percentile in PERCENTILES:
            entry = part[part["percentile"] == percentile].iloc[0]
            row += [format_number(entry["ours"], 2), format_number(entry["paper"], 2)]
        rows.append(row)
    return markdown_table(header, rows) if rows else []


def _stated_lines(table: pd.DataFrame) -> list[str]:
    statements = sorted({s for s in table["stated"] if s})
    return [f"- {s}" for s in statements]


def _thin_lines(summary: pd.DataFrame) -> list[str]:
    """The warning about percentiles resting on too few requests, or nothing."""
    if summary.empty:
        return []
    fewest = int(summary["n_requests"].min())
    thin = thin_percentiles(fewest)
    if not thin:
        return []
    names = ", ".join(PERCENTILE_NAMES[p] for p in thin)
    return [
        f"**Too few test requests for {names}:** a percentile q rests on the n·(1 − q) requests "
        f"beyond it, and with fewer than {MIN_REQUESTS_BEYOND_PERCENTILE} it moves with the luck of "
        f"a handful (p99 needs {MIN_REQUESTS_BEYOND_PERCENTILE * 100:,} test requests). This run has "
        f"{fewest:,} per method (the fewest), so read {names} here, and the ratios and claims "
        "built on them, as rough.",
        "",
    ]


def summary_markdown(summary: pd.DataFrame, run: RunMetadata | None = None) -> str:
    """The run's markdown report: latency table, the paper's ratios, the paper's claims, and
    (in a run with failing servers) each method's success and energy.

    A run outside the paper's setting (:func:`paper.setting_differences`: another topology or
    placement, or a world changed by the run's options) is not scored against the paper: no
    closeness line and no "paper" columns, only a line saying why; its claims are listed for
    information. A run whose percentiles rest on too few requests
    (:func:`files.thin_percentiles`) gets a warning naming them.

    Args:
        summary: from :func:`summarize`.
        run: the run's metadata (names the use case, preset and seed; enables paper columns).

    Returns:
        Markdown text ending with a newline.
    """
    use_case = run.use_case if run else None
    differences = setting_differences(run) if run else []
    # The paper's numbers belong to its setting: outside it, a comparison would score nothing.
    scored_use_case = None if differences else use_case
    lines = _heading_lines(summary, run, differences)
    lines += _latency_lines(summary, run.baseline_reading if run else None)
    table = speedup_table(summary, scored_use_case)
    lines += _speedup_sections(table)
    if use_case is not None:
        lines += _claim_lines(summary, use_case, differences)
    if run is not None and (run.extra.get("failures") or {}).get("enabled"):
        lines += _failure_energy_lines(summary, run)
    return "\n".join(lines) + "\n"


def _heading_lines(summary: pd.DataFrame, run: RunMetadata | None, differences: list[str]) -> list[str]:
    if run:
        title = (f"# SafeTail results: use case {run.use_case} ({run.use_case_name}), "
                 f"preset `{run.preset}`{run.learning_rate_note}, seed {run.seed}{run.settings_note}")
    else:
        title = "# SafeTail results (no run.json: use case, preset and seed unknown)"
    lines = [title, ""]
    if run is not None and (differ := run.extra.get(NOT_THE_LOCK_KEY)):
        lines += [not_the_lock_note(differ), ""]
    numerics = run.extra.get(NUMERICS_KEY) if run is not None else None
    if isinstance(numerics, dict) and not numerics.get("pinned", True):
        lines += [not_pinned_note(numerics), ""]
    lines += _thin_lines(summary)
    if differences:
        lines += [
            "**Closeness to the paper: not scored.** This run is not in the paper's setting: "
            f"{'; '.join(differences)}. The paper's numbers were measured in its own setting, so "
            "the \"paper\" columns are left empty and the claims below are for information.",
            "",
        ]
    elif run is not None and SAFETAIL in set(summary["method"]):
        from yafs_safetail.results.fidelity import run_line  # fidelity reads this module's tables

        lines += [run_line(summary, run.use_case), ""]
    return lines


#: What summary.md says of each reading of MinLoad-x and MinProp-x (docs/calibration.md rule 5).
READING_LINES = {
    "paper-text": "MinLoad-x and MinProp-x as the paper's text reads (§V-B): the x best of all servers.",
    "original-code": "MinLoad-x and MinProp-x as the code behind the paper's numbers chose: the x "
                     "best of three servers drawn at random for each request.",
}


def reading_line(reading: str | None) -> str:
    """The sentence naming the baselines' reading (empty for a run that did not record one)."""
    return "" if reading is None else " " + READING_LINES.get(reading, f"Baselines: {reading}.")


def _latency_lines(summary: pd.DataFrame, reading: str | None = None) -> list[str]:
    n_test = ", ".join(f"{m} {n}" for m, n in zip(summary["method"], summary["n_requests"],
                                                   strict=True))
    lines = [
        "Test phase only. Latencies in seconds; percentiles by numpy's linear interpolation. "
        f"Test requests per method: {n_test or 'none'}.{reading_line(reading)}",
        "",
    ]
    rows = [
        [m, format_number(r.p50_s), format_number(r.p90_s), format_number(r.p95_s), format_number(r.p99_s),
         format_number(r.mean_access_rate), format_number(r.mean_n_selected, 2), format_number(r.mean_target_s),
         format_number(r.target_met_rate), format_number(r.fallback_rate)]
        for m, r in zip(summary["method"], summary.itertuples(index=False), strict=True)
    ]
    return lines + markdown_table(
        ["method", "median", "p90", "p95", "p99", "mean access rate", "mean servers",
         "mean target", "target met", "fallback rate"],
        rows,
    )


def _speedup_sections(table: pd.DataFrame) -> list[str]:
    lines = ["", "## Oracle vs SafeTail", ""]
    oracle_lines = _speedup_lines(table, ORACLE, SAFETAIL)
    if oracle_lines:
        lines += [
            "Oracle's speed-up over SafeTail = SafeTail latency / Oracle latency "
            "(> 1: Oracle faster). \"ours\" is this run; \"paper\" is the paper's stated number "
            "in the same direction (— where the paper states none; where it states SafeTail's "
            "speed-up over Oracle instead, the column shows the reciprocal).",
            "",
            *oracle_lines,
        ]
    else:
        lines.append("Not available: the run lacks SafeTail or Oracle test rows.")
    lines += ["", "## SafeTail vs baselines", ""]
    baseline_lines = _speedup_lines(table, SAFETAIL, None)
    if baseline_lines:
        lines += [
            "SafeTail's speed-up over a baseline = baseline latency / SafeTail latency "
            "(> 1: SafeTail faster). \"ours\" is this run; \"paper\" is the paper's stated "
            "number (— where the paper states none).",
            "",
            *baseline_lines,
        ]
    else:
        lines.append("Not available: the run lacks SafeTail or baseline test rows.")
    stated = _stated_lines(table)
    if stated:
        lines += ["", f"The paper's statements behind the \"paper\" columns ({PAPER_SOURCE}):", "",
                  *stated]
    return lines


def _claim_lines(summary: pd.DataFrame, use_case: int, differences: list[str]) -> list[str]:
    claims = check_claims(summary, use_case)
    if claims.empty:
        return []
    note = ("Where the paper is vague, our reading is written into the statement "
            "(test phase; target = the average target latency).")
    if differences:
        note += " Not the paper's setting (above): for information, not a score."
    lines = ["", "## The paper's qualitative statements", "", note, ""]
    verdict = {True: "yes", False: "no", None: "cannot check"}
    return lines + markdown_table(["paper says", "holds in this run"],
                                  [[t, verdict[h]] for t, h in zip(claims["text"], claims["holds"],
                                                                   strict=True)])


def _failure_energy_lines(summary: pd.DataFrame, run: RunMetadata) -> list[str]:
    """Each method's success and energy in a run whose servers fail (docs/failures_energy.md)."""
    failures = run.extra["failures"]
    timeout_s = failures.get("timeout_s")
    how = (f"each server down {failures['unavailability']:.0%} of the time, mean repair "
           f"{failures['mttr_s']:g} s" if failures.get("mttf_s") else "scripted outages")
    if failures.get("down_file"):
        how += f", outages from {failures['down_file']}"
    lines = ["", "## Failures and energy", "",
             f"Servers fail in this run ({how}); the user waits {format_number(timeout_s)} s for a reply, then "
             "takes the on-device fallback. Success = a reply within that time; energy = the servers' "
             "compute and the device's radio per request (docs/failures_energy.md).", ""]
    header = {"success_rate": "success", "all_lost_rate": "all lost", "timeout_rate": "timed out",
              "all_refused_rate": "all refused", "energy_j_per_request": "energy per request (J)"}
    rows = [[m, *(format_number(getattr(r, c)) for c in header)]
            for m, r in zip(summary["method"], summary.itertuples(index=False), strict=True)]
    return lines + markdown_table(["method", *header.values()], rows)


def write_summary(
    directory: str | os.PathLike[str],
    requests: pd.DataFrame | None = None,
    run: RunMetadata | None = None,
) -> pd.DataFrame:
    """Write ``summary.csv`` and ``summary.md`` into a results folder.

    Args:
        directory: the results folder.
        requests: the requests table; read from ``requests.csv`` when None.
        run: the run's metadata; read from ``run.json`` when None and the file exists.

    Returns:
        The summary DataFrame that was written.
    """
    folder = Path(directory)
    if requests is None:
        requests = read_requests_csv(folder)
    if run is None and (folder / RUN_FILE).is_file():
        run = read_run_json(folder)
    summary = summarize(requests, preset=run.preset if run else "", beta=run.beta if run else None)
    write_text_atomic(folder / SUMMARY_CSV_FILE, _csv_text(summary))
    write_text_atomic(folder / SUMMARY_MD_FILE, summary_markdown(summary, run))
    return summary


def write_results(
    directory: str | os.PathLike[str], requests: pd.DataFrame, run: RunMetadata
) -> pd.DataFrame:
    """Write a run's ``requests.csv``, ``run.json``, ``summary.csv`` and ``summary.md``.

    Args:
        directory: the results folder (must exist).
        requests: the requests table.
        run: the run's metadata.

    Returns:
        The summary DataFrame.
    """
    write_requests_csv(requests, directory)
    write_run_json(directory, run)
    return write_summary(directory, requests, run)

