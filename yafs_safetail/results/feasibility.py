"""What any policy could reach in the worlds of a preset's runs: the verdict over seeds.

``results/world_bounds.py`` reads one run's world and turns the paper's statements about a
percentile into intervals on SafeTail's latency there (its docstring says how each statement
reads); this module gathers the runs of one preset over use cases and seeds: ``feasibility.csv``
(:func:`check_all`), the verdict per use case and percentile (:func:`by_percentile`), the most
any policy could reproduce (:class:`Ceiling`), and REPORT.md's section
(:func:`feasibility_markdown`). ``yafs-safetail feasibility DIR ...`` prints them for run
folders.

The names of ``world_bounds`` are also importable from here (the reports and tests read them as
``feasibility.check``, ``feasibility.bounds``...).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import pandas as pd

from yafs_safetail.results.fidelity import TOLERANCE
from yafs_safetail.results.markdown import frame_markdown
from yafs_safetail.results.paper import PERCENTILE_NAMES
from yafs_safetail.results.world_bounds import (
    FEASIBILITY_COLUMNS,
    GIVE_UP_SEPARATOR,
    LATENCY_CLAIMS,
    SERVER_CLAIMS,
    WORLD_CLAIMS,
    Bound,
    LatencyClaim,
    WorldRun,
    bounds,
    check,
    claim_kind,
    claims_reachable,
    fewest_to_give_up,
    floor_percentiles,
    ratio_ceiling,
    read_world_run,
    unbounded_claims,
)

__all__ = [
    # Per run (world_bounds).
    "FEASIBILITY_COLUMNS", "GIVE_UP_SEPARATOR", "LATENCY_CLAIMS", "SERVER_CLAIMS", "WORLD_CLAIMS",
    "Bound", "LatencyClaim", "WorldRun", "bounds", "check", "claim_kind", "claims_reachable",
    "fewest_to_give_up", "floor_percentiles", "ratio_ceiling", "read_world_run",
    "unbounded_claims",
    # Over the runs of a preset.
    "FEASIBILITY_FILE", "FEASIBILITY_NOTE", "Ceiling", "by_percentile", "ceiling", "ceiling_line",
    "check_all", "feasibility_display", "feasibility_markdown", "reachable_count",
]

FEASIBILITY_FILE = "feasibility.csv"


def check_all(worlds: Sequence[WorldRun]) -> pd.DataFrame:
    """:func:`check` for every run, one frame (the rows of ``feasibility.csv``)."""
    if not worlds:
        return pd.DataFrame(columns=list(FEASIBILITY_COLUMNS))
    return pd.concat([check(w) for w in worlds], ignore_index=True)


def by_percentile(checked: pd.DataFrame) -> pd.DataFrame:
    """Per use case and percentile: in how many seeds some latency satisfies every statement
    (reachable when in most), and the two statements that set the interval's ends most often
    among the seeds that agree with that verdict (``pair_seeds`` of them; where it is not
    reachable, the two that contradict each other), with the median of those seeds' ends; and
    the set of statements to give up (fewest) that most seeds share (``give_up_seeds`` of
    them; empty: none)."""
    rows = []
    for (use_case, percentile), part in checked.groupby(["use_case", "percentile"], sort=True):
        reachable = int(part["feasible"].sum())
        in_most = reachable * 2 > len(part)
        # The ends that decide: the most common pair among the seeds that agree with the verdict.
        deciding = part[part["feasible"] == in_most]
        pairs = list(zip(deciding["low_statement"], deciding["high_statement"], strict=True))
        pair = Counter(pairs).most_common(1)[0][0]
        with_pair = deciding[[p == pair for p in pairs]]
        give_up, give_up_seeds = Counter(part["give_up"]).most_common(1)[0]
        rows.append({
            "use_case": int(use_case), "percentile": int(percentile),
            "reachable_seeds": reachable, "n_seeds": len(part), "reachable": in_most,
            "n_statements": int(part["n_statements"].max()),
            "give_up": give_up, "give_up_seeds": give_up_seeds,
            "pair_seeds": len(with_pair),
            "low_s": float(with_pair["low_s"].median()),
            "high_s": float(with_pair["high_s"].median()),
            "low_statement": pair[0], "high_statement": pair[1],
        })
    return pd.DataFrame(rows)


def reachable_count(checked: pd.DataFrame) -> tuple[int, int]:
    """(percentiles reachable in most seeds, percentiles checked) over every use case."""
    table = by_percentile(checked)
    return int(table["reachable"].sum()), len(table)


@dataclass(frozen=True, slots=True)
class Ceiling:
    """What no policy can exceed in these worlds (the runs of one preset, several use cases).

    Attributes:
        ratios_low, ratios_high: the most published ratios any policy could hold together within
            ±20%, summed over use cases per seed: the smallest and largest over seeds.
        ratios_total: how many published ratios the use cases have.
        claims: claims reachable on their own in most seeds (those that bound nothing here
            count as reachable), out of ``claims_total``.
        unreachable: ``"uc<N> <key>"`` of every claim no policy can make hold in most seeds.
        unbounded: ``"uc<N> <key>"`` of every claim no latency interval expresses (how many
            servers SafeTail sends): counted among ``claims`` as reachable, since this check
            cannot rule them out, and named so that no reader takes them as checked.
    """

    ratios_low: int
    ratios_high: int
    ratios_total: int
    claims: int
    claims_total: int
    unreachable: tuple[str, ...]
    unbounded: tuple[str, ...] = ()


def ceiling(worlds: Sequence[WorldRun]) -> Ceiling:
    """:class:`Ceiling` of runs that share their seeds across use cases."""
    if not worlds:
        raise ValueError("no runs to bound")
    per_seed: dict[int, int] = {}
    totals: dict[int, int] = {}
    verdicts: dict[tuple[int, str], list[bool]] = {}
    for world in worlds:
        most, total = ratio_ceiling(world)
        per_seed[world.seed] = per_seed.get(world.seed, 0) + most
        totals[world.use_case] = total
        for key, reachable in claims_reachable(world).items():
            verdicts.setdefault((world.use_case, key), []).append(reachable is not False)
    unreachable = tuple(f"uc{uc} {key}" for (uc, key), seen in verdicts.items()
                        if sum(seen) * 2 <= len(seen))
    return Ceiling(min(per_seed.values()), max(per_seed.values()), sum(totals.values()),
                   len(verdicts) - len(unreachable), len(verdicts), unreachable,
                   unbounded_claims(sorted(totals)))


def ceiling_line(worlds: Sequence[WorldRun]) -> str:
    """One line: the most any policy could reproduce in these worlds."""
    top = ceiling(worlds)
    ratios = (f"{top.ratios_low}" if top.ratios_low == top.ratios_high
              else f"{top.ratios_low}–{top.ratios_high}")
    notes = []
    if top.unreachable:
        notes.append(f"out of reach: {', '.join(top.unreachable)}")
    if top.unbounded:
        notes.append(f"not expressible as a latency bound, so counted as reachable: "
                     f"{', '.join(top.unbounded)}")
    missing = f" ({'; '.join(notes)})" if notes else ""
    return (f"Whatever the policy, in these worlds: at most {ratios} of the {top.ratios_total} "
            f"published ratios within ±{TOLERANCE:.0%} together (per seed), and at most "
            f"{top.claims} of the {top.claims_total} claims{missing}.")


def _seconds(value: float) -> str:
    return "—" if math.isinf(value) else f"{value:.3f}"


FEASIBILITY_NOTE = (
    "Could any policy hold the paper's statements about one percentile together in this world? "
    "Each statement is an interval on SafeTail's latency at that percentile: the floor (no "
    "policy beats Oracle, or the on-device fallback), each published ratio within ±20%, and the "
    "claims about SafeTail's latency. Only Oracle's and the baselines' latencies and the targets "
    "are read, never SafeTail's. Reachable: the intervals meet in most seeds. The two statements "
    "are those that set the lower and upper end most often (where it is not reachable: the two "
    "that contradict each other), the ends the median over those seeds. Fewest to give up: the "
    "smallest set of statements without which the rest meet, as most seeds have it. A necessary "
    "condition only: the claims about how many servers SafeTail uses bound no latency and are left out."
)


def feasibility_display(checked: pd.DataFrame) -> pd.DataFrame:
    """The report's table as display strings, one row per use case and percentile (the
    markdown and the LaTeX table are both made from it)."""
    table = by_percentile(checked)
    return pd.DataFrame(
        [[str(r.use_case), PERCENTILE_NAMES[r.percentile], str(r.n_statements),
          f"{r.reachable_seeds} of {r.n_seeds}", _seconds(r.low_s), r.low_statement,
          _seconds(r.high_s), r.high_statement,
          (r.give_up.replace(GIVE_UP_SEPARATOR, "; ") if r.give_up else "nothing")
          + f" ({r.give_up_seeds} of {r.n_seeds})"]
         for r in table.itertuples(index=False)],
        dtype=object,
        columns=["use case", "percentile", "statements", "reachable in seeds", "lower end (s)",
                 "set by", "upper end (s)", "set by", "fewest to give up (in seeds)"])


def feasibility_markdown(checked: pd.DataFrame) -> str:
    """REPORT.md's part: the count, the note, the table."""
    count = reachable_count(checked)
    lines = [f"Percentiles at which the paper's statements can hold together: {count[0]} of "
             f"{count[1]}.", "", FEASIBILITY_NOTE, ""]
    unbounded = unbounded_claims(sorted({int(u) for u in checked["use_case"]}))
    if unbounded:
        lines += [f"Claims no latency interval expresses, so not part of this check: "
                  f"{', '.join(unbounded)}.", ""]
    lines += frame_markdown(feasibility_display(checked))
    return "\n".join(lines) + "\n"
