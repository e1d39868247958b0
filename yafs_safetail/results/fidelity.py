"""The fidelity scorecard: every number and claim the paper publishes, against ours.

For each of the paper's 23 stated ratios (``paper_results.PAPER_RATIOS``) and 11 qualitative
claims (``paper_results.PAPER_CLAIMS``), across the seeds of one preset: the paper's value,
ours (a ratio: the geometric mean over seeds with a 95% t-interval on the log scale, so it never
leaves (0, ∞); a claim: the share of seeds in which it holds), the relative error, whether it
is within ±20%, and whether the number belongs to the calibration subset (the sixteen numbers
whose combination ``experiments/calibrate.py`` fits the world to) or is held out. SafeTail's mean access rate per use case
(the goal: at most 0.5) is reported beside them. UC2's and UC3's ratios and every claim are held
out: calibration rule 6 counted UC3's on the calibration side from 7a364ea, and 3fa44db undid
that with rule 6's world (docs/calibration.md; ``tests/test_fidelity.py`` pins each ratio's side).

Reads summaries only (``summary.csv`` of each run folder); never the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import SAFETAIL
from yafs_safetail.results.claims import check_claims
from yafs_safetail.results.figures.fidelity import draw_scorecard as draw_scorecard
from yafs_safetail.results.markdown import frame_markdown
from yafs_safetail.results.over_seeds import bootstrap_interval, geometric_interval
from yafs_safetail.results.paper import (
    PAPER_CLAIMS,
    PAPER_RATIOS,
    PERCENTILE_NAMES,
    in_calibration_subset,
)
from yafs_safetail.results.stats import speedup

#: A ratio is reproduced when ours is within this relative distance of the paper's.
TOLERANCE = 0.20
#: The access-rate goal of the default preset (SafeTail's mean access rate at most this).
ACCESS_RATE_GOAL = 0.5
FIDELITY_FILE = "fidelity.csv"
FIDELITY_FIGURE = "fidelity"

FIDELITY_COLUMNS: tuple[str, ...] = (
    "kind", "use_case", "key", "statement", "paper", "ours", "ci_low", "ci_high", "n_seeds",
    "relative_error", "within_tolerance", "subset",
)


def _ratio_key(method: str, reference: str, percentile: int) -> str:
    return f"{method} over {reference} {PERCENTILE_NAMES[percentile]}"


def scorecard(summaries: Mapping[int, Sequence[pd.DataFrame]]) -> pd.DataFrame:
    """The scorecard from per-seed summaries of each use case.

    Args:
        summaries: use case -> one test-phase summary per seed (``results.summarize``).

    Returns:
        Columns ``FIDELITY_COLUMNS``; ``kind`` is ``ratio``, ``claim`` or ``access_rate``;
        ``subset`` is ``calibration`` or ``held-out`` for ratios (claims and access rates are
        never calibrated: ``held-out``); use cases without summaries are left out.
    """
    rows = []
    for ratio in PAPER_RATIOS:
        runs = summaries.get(ratio.use_case, ())
        if not runs:
            continue
        values = [speedup(s, ratio.method, ratio.reference, ratio.percentile) for s in runs]
        ours, low, high = geometric_interval(values)
        rows.append({
            "kind": "ratio", "use_case": ratio.use_case,
            "key": _ratio_key(ratio.method, ratio.reference, ratio.percentile),
            "statement": ratio.stated, "paper": ratio.speedup, "ours": ours, "ci_low": low,
            "ci_high": high, "n_seeds": len(values),
            "relative_error": ours / ratio.speedup - 1.0,
            "within_tolerance": bool(abs(ours / ratio.speedup - 1.0) <= TOLERANCE),
            "subset": "calibration" if in_calibration_subset(ratio) else "held-out",
        })
    for claim in PAPER_CLAIMS:
        runs = summaries.get(claim.use_case, ())
        if not runs:
            continue
        verdicts = [check_claims(s, claim.use_case).set_index("key").loc[claim.key, "holds"]
                    for s in runs]
        checked = [bool(v) for v in verdicts if v is not None]
        share = float(np.mean(checked)) if checked else math.nan
        rows.append({
            "kind": "claim", "use_case": claim.use_case, "key": claim.key,
            "statement": claim.text, "paper": 1.0, "ours": share, "ci_low": math.nan,
            "ci_high": math.nan, "n_seeds": len(checked), "relative_error": math.nan,
            # A claim holds when it holds in most seeds.
            "within_tolerance": bool(checked) and share > 0.5, "subset": "held-out",
        })
    for use_case in sorted(summaries):
        runs = summaries[use_case]
        values = [float(s.loc[s["method"] == SAFETAIL, "mean_access_rate"].iloc[0])
                  for s in runs if (s["method"] == SAFETAIL).any()]
        if not values:
            continue
        ours, low, high = bootstrap_interval(values)
        rows.append({
            "kind": "access_rate", "use_case": use_case, "key": "SafeTail mean access rate",
            "statement": f"goal: at most {ACCESS_RATE_GOAL}", "paper": ACCESS_RATE_GOAL,
            "ours": ours, "ci_low": low, "ci_high": high, "n_seeds": len(values),
            "relative_error": math.nan, "within_tolerance": bool(ours <= ACCESS_RATE_GOAL),
            "subset": "held-out",
        })
    return pd.DataFrame(rows, columns=list(FIDELITY_COLUMNS))


def counts(card: pd.DataFrame) -> dict[str, tuple[int, int]]:
    """(hits, total) for: all ratios, the calibration subset, held-out ratios, claims, access."""
    ratios = card[card["kind"] == "ratio"]

    def tally(frame: pd.DataFrame) -> tuple[int, int]:
        return int(frame["within_tolerance"].sum()), len(frame)

    return {
        "ratios": tally(ratios),
        "calibration": tally(ratios[ratios["subset"] == "calibration"]),
        "held-out": tally(ratios[ratios["subset"] == "held-out"]),
        "claims": tally(card[card["kind"] == "claim"]),
        "access_rate": tally(card[card["kind"] == "access_rate"]),
    }


def _share(pair: tuple[int, int]) -> str:
    hits, total = pair
    return f"{hits} of {total}" + (f" ({hits / total:.0%})" if total else "")


def counts_line(card: pd.DataFrame) -> str:
    """One line: how close these runs are to the paper."""
    c = counts(card)
    return (f"Ratios within ±{TOLERANCE:.0%} of the paper: {_share(c['ratios'])} — calibration "
            f"subset {_share(c['calibration'])}, held out {_share(c['held-out'])}; claims that "
            f"hold: {_share(c['claims'])}; SafeTail access rate ≤ {ACCESS_RATE_GOAL}: "
            f"{_share(c['access_rate'])} use cases.")


def _number(value: float, digits: int = 2) -> str:
    return "—" if value is None or math.isnan(value) else f"{value:.{digits}f}"


#: The notes over the scorecard's tables (REPORT.md and the LaTeX tables).
SCORECARD_RATIO_NOTE = (
    "Ratio = speed-up of the first-named method (latency of the second / latency of the "
    "first, > 1: first faster). Ours: geometric mean over seeds [95% t-interval on the log "
    "scale]. Calibration = one of the sixteen numbers whose combination (each x = 1 baseline's "
    "latency over Oracle's) the unpublished world parameters were fitted to, without SafeTail "
    "(experiments/calibrate.py); held out = never used to choose or fit anything."
)
SCORECARD_CLAIM_NOTE = "Claims (our reading written into the statement; holds = in most seeds):"
SCORECARD_ACCESS_NOTE = (f"SafeTail's mean access rate (goal ≤ {ACCESS_RATE_GOAL}; mean over seeds "
                         "[95% bootstrap interval]):")


def _interval(low: float, high: float, digits: int) -> str:
    return "" if math.isnan(low) else f" [{low:.{digits}f}, {high:.{digits}f}]"


def scorecard_tables(card: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The scorecard's three tables as display strings (the markdown and LaTeX share them).

    Args:
        card: from :func:`scorecard`.

    Returns:
        ``{"ratios": ..., "claims": ..., "access_rate": ...}``, each a frame of strings whose
        columns are the table's header.
    """
    ratio_rows = [
        [str(row.use_case), row.key, _number(row.paper), _number(row.ours) + _interval(row.ci_low, row.ci_high, 2),
         f"{row.relative_error:+.0%}", "yes" if row.within_tolerance else "no", row.subset]
        for row in card[card["kind"] == "ratio"].itertuples(index=False)
    ]
    claim_rows = [
        [str(row.use_case), row.statement, f"{row.ours:.0%} of {row.n_seeds}",
         "yes" if row.within_tolerance else "no"]
        for row in card[card["kind"] == "claim"].itertuples(index=False)
    ]
    access_rows = [
        [str(row.use_case), _number(row.ours, 3) + _interval(row.ci_low, row.ci_high, 3),
         "yes" if row.within_tolerance else "no"]
        for row in card[card["kind"] == "access_rate"].itertuples(index=False)
    ]
    return {
        "ratios": pd.DataFrame(ratio_rows, dtype=object, columns=[
            "use case", "ratio", "paper", "ours", "error", f"within ±{TOLERANCE:.0%}", "subset"]),
        "claims": pd.DataFrame(claim_rows, dtype=object, columns=[
            "use case", "the paper says", "holds in seeds", "holds"]),
        "access_rate": pd.DataFrame(access_rows, dtype=object, columns=[
            "use case", "access rate", "meets goal"]),
    }


def scorecard_markdown(card: pd.DataFrame) -> str:
    """The scorecard as markdown: the counts, then one table of ratios and one of claims."""
    tables = scorecard_tables(card)
    lines = [counts_line(card), "",
             SCORECARD_RATIO_NOTE, "", *frame_markdown(tables["ratios"]), "",
             SCORECARD_CLAIM_NOTE, "", *frame_markdown(tables["claims"]), "",
             SCORECARD_ACCESS_NOTE, "", *frame_markdown(tables["access_rate"])]
    return "\n".join(lines) + "\n"


def run_line(summary: pd.DataFrame, use_case: int) -> str:
    """The one line a run's summary.md gives: how close this single run is to the paper."""
    card = scorecard({use_case: [summary]})
    c = counts(card)
    if not c["ratios"][1]:
        return "The paper states no ratio this run can be compared with."
    # Name only the parts this use case has (use case 1's ratios are all calibration numbers).
    parts = [f"{name} {_share(c[key])}" for key, name in (("calibration", "calibration subset"),
                                                         ("held-out", "held out")) if c[key][1]]
    return (f"**Closeness to the paper (this run): {_share(c['ratios'])} of the paper's ratios for "
            f"use case {use_case} within ±{TOLERANCE:.0%}** ({', '.join(parts)}); claims that hold: "
            f"{_share(c['claims'])}. One seed only: `experiments/reproduce_all.py` gives intervals "
            "over seeds.")
