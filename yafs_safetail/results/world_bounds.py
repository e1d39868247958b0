"""Per run: which of the paper's statements any policy could hold together in one world.

The scorecard (``results/fidelity.py``) says how close SafeTail came to each published number.
This module asks a question about the *world* instead: given the latencies Oracle and the
baselines measured, and the targets τ of the requests, is there any SafeTail latency at a
percentile that satisfies every published statement about that percentile at once? If not, no
policy, however well trained, can reproduce those statements together in that world, and a
miss among them is the world's (or the paper's), not the learner's.

Each statement becomes an interval on SafeTail's q-th percentile latency S_q (seconds):

* **the floor**: no policy beats Oracle's latency on any request, nor the on-device fallback
  where some server refused it (a policy's reply is the fastest of its accepting servers, or
  the fallback when all of them refuse, and Oracle asks every server), so S_q ≥ the q-th
  percentile of that per-request minimum. Computed from Oracle's test rows in ``requests.csv``
  (their latency and ``refused``).
* **a published ratio r** of SafeTail against a method M, counted as reproduced within ±20%
  (``fidelity.TOLERANCE``): ``latency(M) / S_q ∈ [0.8 r, 1.2 r]`` for "SafeTail over M",
  ``S_q / latency(M) ∈ [0.8 r, 1.2 r]`` for "M over SafeTail".
* **a claim about SafeTail's latency** (``paper.PAPER_CLAIMS``): below the average target
  (S_q < τ̄), faster than every x = 2, 3 baseline (S_q < the fastest of them), faster than
  MinProp-3 (S_q < its q-latency), and UC3's pair read with one quantifier: faster than more
  than half of the N baselines run (S_q < the m-th slowest, m = ⌊N/2⌋ + 1) or more than half
  of them faster than SafeTail (S_q > the m-th fastest).

The intersection is empty exactly when two statements contradict each other in this world.
The claims' inequalities are strict, as the scorecard tests them (a baseline whose p99 is
Oracle's own cannot be beaten there); each percentile is checked on its own, so this is a
necessary condition only (generous to the paper). Every claim is one of three kinds
(:func:`claim_kind`): a bound on SafeTail's latency (above), a fact of the world (Oracle's p99
above the target: it holds or not whatever the policy), or a statement about how many servers
SafeTail sends, which no latency interval can express: those are reported as such
(:func:`claims_reachable` gives None, ``feasibility.Ceiling`` and the reports name them), not checked,
and a percentile that passes may still be out of reach for a policy that must also hold them.
A claim of none of the three kinds is an error, so a new claim cannot slip through unread.
SafeTail's own latencies are never read.

Only the single-user world (``run_usecase.py``) makes every method face the same requests with
the same server states whatever the others choose; that is what makes the floor and the
baselines' latencies properties of the world.

This module reads one run's world and checks it; ``results/feasibility.py`` gathers the runs of
a preset (the verdict over seeds, the ceiling, ``feasibility.csv`` and REPORT.md's section).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import ORACLE, SAFETAIL, baselines_of, parse_method
from yafs_safetail.results.fidelity import TOLERANCE
from yafs_safetail.results.files import (
    PERCENTILES,
    ResultsFileError,
    read_requests_csv,
    read_summary_csv,
)
from yafs_safetail.results.paper import MINPROP_3, PAPER_CLAIMS, PAPER_RATIOS, PERCENTILE_NAMES
from yafs_safetail.results.run_json import read_run_json


@dataclass(frozen=True, slots=True)
class LatencyClaim:
    """A claim read as a bound on SafeTail's q-th percentile latency S_q.

    Attributes:
        percentiles: the percentiles it bounds.
        side: ``high``: S_q below the reference; ``low``: above it (strict either way).
        reference: ``target`` (the average target), ``x23`` (the fastest Rand/MinLoad/MinProp
            with x = 2 or 3), ``majority`` (the baseline that decides "more than half of the
            baselines run": see :func:`_claim_reference`), or a method's name (its latency).
        label: names the statement in reports; ``{reference}`` becomes what set the bound.
    """

    percentiles: tuple[int, ...]
    side: str
    reference: str
    label: str


#: The claims that bound SafeTail's latency, by key.
LATENCY_CLAIMS: dict[str, LatencyClaim] = {
    "below_target_all": LatencyClaim(PERCENTILES, "high", "target",
                                     "claim: below {reference} at every percentile"),
    "median_below_target": LatencyClaim((50,), "high", "target", "claim: median below {reference}"),
    "below_target_p50_p90": LatencyClaim((50, 90), "high", "target",
                                         "claim: median, p90 below {reference}"),
    "beats_x23_all": LatencyClaim(PERCENTILES, "high", "x23",
                                  "claim: faster than every x = 2, 3 baseline ({reference})"),
    "beats_minprop3_tails": LatencyClaim((90, 95, 99), "high", MINPROP_3,
                                         "claim: faster than {reference} at p90, p95, p99"),
    "safetail_better_p95_p99": LatencyClaim((95, 99), "high", "majority",
                                            "claim: faster than most baselines at p95, p99 "
                                            "({reference})"),
    "baseline_better_p50_p90": LatencyClaim((50, 90), "low", "majority",
                                            "claim: most baselines faster at median, p90 "
                                            "({reference})"),
}
#: Claims about the world alone: Oracle's latencies against the target, whatever the policy.
WORLD_CLAIMS: frozenset[str] = frozenset({"oracle_tail_above_target"})
#: Claims about how many servers SafeTail sends: no interval on its latency expresses them.
SERVER_CLAIMS: frozenset[str] = frozenset({"servers_1_to_3", "mean_servers_2_to_3",
                                           "mostly_1_to_2_servers"})


def claim_kind(key: str) -> str:
    """``latency``, ``world`` or ``servers``: how this check reads the claim ``key``.

    Raises:
        KeyError: a claim of none of the three kinds (a new claim must be given one here).
    """
    if key in LATENCY_CLAIMS:
        return "latency"
    if key in WORLD_CLAIMS:
        return "world"
    if key in SERVER_CLAIMS:
        return "servers"
    raise KeyError(f"feasibility: no reading of paper claim {key!r} (latency, world or servers)")


def unbounded_claims(use_cases: Sequence[int]) -> tuple[str, ...]:
    """``"uc<N> <key>"`` of every claim of these use cases that no latency interval expresses."""
    wanted = set(use_cases)
    return tuple(f"uc{c.use_case} {c.key}" for c in PAPER_CLAIMS
                 if c.use_case in wanted and claim_kind(c.key) == "servers")


FEASIBILITY_COLUMNS: tuple[str, ...] = (
    "use_case", "seed", "percentile", "floor_s", "low_s", "high_s", "feasible", "low_statement",
    "high_statement", "n_statements", "give_up",
)
#: Joins the statements of ``give_up`` (none of them contains it).
GIVE_UP_SEPARATOR = " | "


@dataclass(frozen=True, slots=True)
class WorldRun:
    """What one run tells about its world: never SafeTail's own latencies.

    Attributes:
        use_case: 1, 2 or 3.
        seed: the run's seed.
        summary: the test-phase summary (Oracle's and the baselines' percentiles, τ's mean).
        floor_s: percentile -> the q-latency no policy can beat (see the module docstring).
    """

    use_case: int
    seed: int
    summary: pd.DataFrame
    floor_s: Mapping[int, float]


@dataclass(frozen=True, slots=True)
class Bound:
    """One statement as an interval on SafeTail's q-latency (seconds).

    Attributes:
        kind: ``floor``, ``ratio`` or ``claim``.
        key: the claim's key (``paper.PAPER_CLAIMS``); the statement for the others.
        strict: the end it sets is excluded (the claims: "below", "faster" as
            ``claims.check_claims`` tests them); the floor and the ±20% ratios include theirs.
    """

    percentile: int
    statement: str
    low_s: float
    high_s: float
    kind: str
    key: str
    strict: bool = False


def floor_percentiles(oracle_latency_s: np.ndarray, fallback_latency_s: float,
                      fallback_reachable: np.ndarray | None = None) -> dict[int, float]:
    """Per percentile, the latency no policy can beat: per request, Oracle's latency, or the
    fallback where that is faster and some server refused the request.

    A policy meets the fallback only when every server it chose refuses, so only on requests
    where at least one server refused (Oracle's ``refused`` > 0: it asks every server); on the
    others the fallback is out of any policy's reach. Every order statistic of a policy's
    latencies is at least the same order statistic of these minima, so the interpolated
    percentile is too (numpy's default, as everywhere).

    Args:
        oracle_latency_s: Oracle's latency per test request.
        fallback_latency_s: the on-device fallback latency.
        fallback_reachable: per request, whether some server refused it (None: assume every
            request, a looser floor).
    """
    if oracle_latency_s.size == 0:
        raise ValueError("no Oracle test rows: the floor needs Oracle's latencies")
    reachable = np.ones(oracle_latency_s.shape, bool) if fallback_reachable is None else fallback_reachable
    floor = np.where(reachable, np.minimum(oracle_latency_s, fallback_latency_s), oracle_latency_s)
    return {p: float(np.percentile(floor, p)) for p in PERCENTILES}


def read_world_run(folder: str | Path) -> WorldRun:
    """A run folder's world: ``run.json``, ``summary.csv`` and Oracle's rows of ``requests.csv``.

    Raises:
        ResultsFileError: a file is missing or malformed (one line naming it).
        ValueError: the run has no Oracle test rows, or ``run.json`` no fallback latency.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ResultsFileError(f"{folder}: results folder not found")
    run = read_run_json(folder)
    fallback = run.extra.get("fallback_latency_s")
    if not isinstance(fallback, (int, float)) or isinstance(fallback, bool):
        raise ValueError(f"{folder / 'run.json'}: key fallback_latency_s: expected a number, "
                         f"got {fallback!r}")
    requests = read_requests_csv(folder / "requests.csv")
    oracle = requests[(requests["method"] == ORACLE) & (requests["phase"] == "test")]
    try:
        floor = floor_percentiles(oracle["latency_s"].to_numpy(float), float(fallback),
                                  oracle["refused"].to_numpy() > 0)
    except ValueError as error:
        raise ValueError(f"{folder / 'requests.csv'}: {error}") from None
    return WorldRun(run.use_case, run.seed, read_summary_csv(folder), floor)


def _latency(summary: pd.DataFrame, method: str, percentile: int) -> float:
    row = summary[summary["method"] == method]
    return math.nan if row.empty else float(row[f"p{percentile}_s"].iloc[0])


def _average_target(summary: pd.DataFrame) -> float:
    row = summary[summary["method"].isin([SAFETAIL, ORACLE])]
    # τ is the request's, not the policy's: every method's rows carry the same targets.
    return math.nan if row.empty else float(row["mean_target_s"].iloc[0])


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


def _claim_reference(summary: pd.DataFrame, claim: LatencyClaim, percentile: int) -> tuple[float, str]:
    """The latency that bounds S_q for ``claim`` and what it is, or (NaN, "") when the run lacks
    what it needs. For ``majority`` over the N baselines with a latency at q, ascending, and
    m = ⌊N/2⌋ + 1 (more than half): "more than half faster than SafeTail" is S_q > the m-th
    fastest; "SafeTail faster than more than half" is S_q < the m-th slowest."""
    if claim.reference == "target":
        target = _average_target(summary)
        return (math.nan, "") if math.isnan(target) else (target, "the average target")
    if claim.reference not in ("x23", "majority"):
        latency = _latency(summary, claim.reference, percentile)
        return (math.nan, "") if math.isnan(latency) else (latency, claim.reference)
    names = baselines_of(summary["method"])
    if claim.reference == "x23":
        names = [b for b in names if parse_method(b)[1] in (2, 3)]
    latencies = {b: _latency(summary, b, percentile) for b in names}
    ranked = sorted((b for b in names if not math.isnan(latencies[b])), key=lambda b: latencies[b])
    if not ranked:
        return math.nan, ""
    if claim.reference == "x23":
        return latencies[ranked[0]], ranked[0]
    n = len(ranked)
    m = n // 2 + 1
    rank = m if claim.side == "low" else n - m + 1
    name = ranked[rank - 1]
    return latencies[name], f"{name}, {_ordinal(rank)} fastest of {n}"


def bounds(world: WorldRun) -> list[Bound]:
    """Every statement the paper makes about ``world.use_case`` that bounds SafeTail's latency."""
    floor = "floor: no policy beats Oracle (or the fallback)"
    out = [Bound(p, floor, world.floor_s[p], math.inf, "floor", floor) for p in PERCENTILES]
    for ratio in PAPER_RATIOS:
        if ratio.use_case != world.use_case or SAFETAIL not in (ratio.method, ratio.reference):
            continue
        other = ratio.reference if ratio.method == SAFETAIL else ratio.method
        latency = _latency(world.summary, other, ratio.percentile)
        if math.isnan(latency):
            continue
        low_r, high_r = ratio.speedup * (1 - TOLERANCE), ratio.speedup * (1 + TOLERANCE)
        if ratio.method == SAFETAIL:  # speed-up = latency(other) / S
            interval = (latency / high_r, latency / low_r)
        else:  # speed-up of other over SafeTail = S / latency(other)
            interval = (latency * low_r, latency * high_r)
        name = f"{ratio.method} over {ratio.reference} {PERCENTILE_NAMES[ratio.percentile]}"
        text = f"{name} = {ratio.speedup:g} ±{TOLERANCE:.0%}"
        out.append(Bound(ratio.percentile, text, *interval, "ratio", text))
    for claim in PAPER_CLAIMS:
        # claim_kind raises for a claim it cannot read: none is left out unnoticed.
        if claim.use_case != world.use_case or claim_kind(claim.key) != "latency":
            continue
        reading = LATENCY_CLAIMS[claim.key]
        for p in reading.percentiles:
            value, source = _claim_reference(world.summary, reading, p)
            if math.isnan(value):
                continue
            text = reading.label.format(reference=source)
            low, high = (-math.inf, value) if reading.side == "high" else (value, math.inf)
            out.append(Bound(p, text, low, high, "claim", claim.key, strict=True))
    return out


def _meet(bounds_: Sequence[Bound]) -> bool:
    low = max(b.low_s for b in bounds_)
    high = min(b.high_s for b in bounds_)
    if low != high:
        return low < high
    # One point left: it must belong to every bound that ends there.
    return not any(b.strict for b in bounds_ if low in (b.low_s, b.high_s))


def fewest_to_give_up(bounds_: Sequence[Bound]) -> tuple[Bound, ...]:
    """The smallest set of statements whose removal lets the others meet (the floor is a fact
    of the world and is never given up); among equally small sets, the first in the order of
    ``bounds_``. Empty when they meet already."""
    floor, statements = bounds_[0], list(bounds_[1:])
    for size in range(len(statements) + 1):
        for dropped in itertools.combinations(range(len(statements)), size):
            kept = [floor] + [b for i, b in enumerate(statements) if i not in dropped]
            if _meet(kept):
                return tuple(statements[i] for i in dropped)
    raise AssertionError("the floor alone always meets")  # pragma: no cover


def check(world: WorldRun) -> pd.DataFrame:
    """Per percentile: the intersection of every bound, whether it is empty, which two
    statements set its ends, and the fewest statements to give up for the rest to meet
    (columns ``FEASIBILITY_COLUMNS``)."""
    rows = []
    every = bounds(world)
    for p in PERCENTILES:
        mine = [b for b in every if b.percentile == p]  # the floor first
        lowest = max(mine, key=lambda b: b.low_s)
        highest = min(mine, key=lambda b: b.high_s)
        rows.append({
            "use_case": world.use_case, "seed": world.seed, "percentile": p,
            "floor_s": world.floor_s[p], "low_s": lowest.low_s, "high_s": highest.high_s,
            "feasible": _meet(mine),
            "low_statement": lowest.statement, "high_statement": highest.statement,
            "n_statements": len(mine) - 1,
            "give_up": GIVE_UP_SEPARATOR.join(b.statement for b in fewest_to_give_up(mine)),
        })
    return pd.DataFrame(rows, columns=list(FEASIBILITY_COLUMNS))


def ratio_ceiling(world: WorldRun) -> tuple[int, int]:
    """(the most of the use case's published ratios any policy could hold together within
    ±20% in this world, how many there are): per percentile, the ratios less the fewest of them
    to give up for the rest to meet the floor; claims left out."""
    every = bounds(world)
    most = total = 0
    for p in PERCENTILES:
        mine = [b for b in every if b.percentile == p and b.kind != "claim"]  # the floor first
        total += len(mine) - 1
        most += len(mine) - 1 - len(fewest_to_give_up(mine))
    return most, total


def claims_reachable(world: WorldRun) -> dict[str, bool | None]:
    """Each of the use case's claims on its own: could any policy make it hold in this world?

    A claim about SafeTail's latency is reachable when, at each of its percentiles, its bound
    meets the floor. "Even Oracle's p99 exceeds the average target" is a fact of the world
    (reachable when it holds). The claims about how many servers SafeTail uses bound nothing
    here: None (:func:`unbounded_claims` names them for the reports), as is a latency claim
    whose reference the run lacks (e.g. no MinProp-3).

    Raises:
        KeyError: a claim :func:`claim_kind` cannot read.
    """
    every = bounds(world)
    floors = {b.percentile: b for b in every if b.kind == "floor"}
    out: dict[str, bool | None] = {}
    for claim in PAPER_CLAIMS:
        if claim.use_case != world.use_case:
            continue
        kind = claim_kind(claim.key)
        if kind == "world":
            oracle = _latency(world.summary, ORACLE, 99)
            out[claim.key] = None if math.isnan(oracle) else bool(oracle > _average_target(world.summary))
        elif kind == "latency":
            mine = [b for b in every if b.key == claim.key]
            # No bound (e.g. no x = 2, 3 baseline in the run): nothing to check, as check_claims.
            out[claim.key] = all(_meet([floors[b.percentile], b]) for b in mine) if mine else None
        else:
            out[claim.key] = None
    return out
