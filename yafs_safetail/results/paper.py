"""The paper's published headline results, as data.

Every entry is copied from the "Published headline results" table of
``/work/shared/spec/facts.md``, which restates §V of the paper (use cases 1, 2 and 3). Nothing
here is measured by this project.

The paper states its ratios in two directions: "Oracle ... speed-up in median latency of 1.08x
compared to SafeTail" (Oracle's speed-up over SafeTail) and "SafeTail experienced speed-ups ...
of 0.93x ... compared to Oracle" (SafeTail's speed-up over Oracle). Each entry keeps the
direction in which the paper states it; :func:`paper_speedup` converts to whichever direction
is asked for (a speed-up of A over B is ``latency(B) / latency(A)``, so the two directions are
reciprocals).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from yafs_safetail.edge.calibration import WORLD_NAMES
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY, REPOSITORY
from yafs_safetail.methods.registry import ORACLE, SAFETAIL, baselines_of
from yafs_safetail.results.files import PERCENTILES
from yafs_safetail.results.over_seeds import geometric_interval, load_runs
from yafs_safetail.results.run_json import PLACEMENT_KEY, WORLD_OVERRIDES_KEY, RunMetadata
from yafs_safetail.results.stats import speedup

PERCENTILE_NAMES: dict[int, str] = {50: "median", 90: "p90", 95: "p95", 99: "p99"}


@dataclass(frozen=True, slots=True)
class PaperRatio:
    """One ratio stated in the paper.

    Attributes:
        use_case: 1, 2 or 3.
        method: the method whose speed-up is stated ("Oracle", "SafeTail", ...).
        reference: the method it is compared with.
        percentile: 50, 90, 95 or 99.
        speedup: ``latency(reference) / latency(method)`` as the paper states it
            (> 1: ``method`` is faster).
        stated: the statement as facts.md words it, for reports.
    """

    use_case: int
    method: str
    reference: str
    percentile: int
    speedup: float
    stated: str


def _ratios(
    use_case: int, method: str, reference: str, values: dict[int, float], stated: str
) -> list[PaperRatio]:
    return [
        PaperRatio(use_case, method, reference, percentile, value, stated)
        for percentile, value in values.items()
    ]


PAPER_RATIOS: tuple[PaperRatio, ...] = tuple(
    # Use case 1 (facts.md row 1).
    _ratios(1, "Oracle", "SafeTail", {50: 1.08}, "Oracle median 1.08x faster than SafeTail")
    + _ratios(
        1, "SafeTail", "Oracle", {90: 0.93, 95: 0.92, 99: 0.79},
        "SafeTail vs Oracle at p90/p95/p99: 0.93x / 0.92x / 0.79x",
    )
    + _ratios(
        1, "SafeTail", "Rand-1", {50: 1.72, 90: 2.64, 95: 2.62, 99: 2.24},
        "SafeTail median 1.72x, tails 2.64/2.62/2.24x faster than Rand-1",
    )
    + _ratios(
        1, "SafeTail", "MinLoad-1", {50: 1.11, 90: 1.37, 95: 1.66, 99: 1.69},
        "SafeTail median 1.11x, tails 1.37/1.66/1.69x faster than MinLoad-1",
    )
    + _ratios(
        1, "SafeTail", "MinProp-1", {50: 1.13, 90: 1.63, 95: 1.99, 99: 1.89},
        "SafeTail median 1.13x, tails 1.63/1.99/1.89x faster than MinProp-1",
    )
    # Use case 2 (facts.md row 2): baseline latency as a multiple of SafeTail's, which is
    # SafeTail's speed-up over that baseline.
    + _ratios(2, "SafeTail", "Rand-3", {50: 0.97}, "Rand-3 median 0.97x of SafeTail")
    + _ratios(2, "SafeTail", "MinLoad-3", {90: 0.90}, "MinLoad-3 p90 0.90x of SafeTail")
    + _ratios(2, "SafeTail", "MinProp-3", {50: 0.98}, "MinProp-3 median 0.98x of SafeTail")
    # Use case 3 (facts.md row 3).
    + _ratios(
        3, "Oracle", "SafeTail", {50: 1.50, 90: 1.14, 95: 1.12, 99: 1.00},
        "Oracle faster by 1.50x / 1.14x / 1.12x / 1.00x (median / p90 / p95 / p99)",
    )
)


@dataclass(frozen=True, slots=True)
class PaperClaim:
    """A qualitative statement of the paper that a run can be checked against.

    Attributes:
        use_case: 1, 2 or 3.
        key: a stable identifier; ``results.check_claims`` knows how to test each key.
        text: the statement, with this project's reading of it where the paper is vague.
    """

    use_case: int
    key: str
    text: str


#: The method UC2's "SafeTail outperformed MinProp-3 in other cases" names.
MINPROP_3 = "MinProp-3"

# The readings (docs/results.md, "The paper's claims and how they are read"):
# * UC3's "the baseline methods outperformed SafeTail" (median, p90) and "SafeTail performed
#   better" (p95, p99) get one quantifier on both sides: more than half of the Rand/MinLoad/
#   MinProp baselines run. "The baseline methods" is a plural with no "all" or "some", and the
#   abstract's own summary is "outperformed most baseline strategies".
# * A statement about how many servers SafeTail uses must not hold for a policy that does not
#   vary: "varies between 1 and 3", "uses 1-3, mostly 1-2" and "on average 2 to 3 and in some
#   cases just 1" are all false of a policy that sends the same number of servers every time.
PAPER_CLAIMS: tuple[PaperClaim, ...] = (
    PaperClaim(1, "below_target_all",
               "SafeTail below the average target latency at median, p90, p95 and p99"),
    PaperClaim(1, "beats_x23_all",
               "SafeTail faster than Rand/MinLoad/MinProp with x = 2, 3 at every percentile"),
    PaperClaim(1, "servers_1_to_3",
               "SafeTail's access rate varies between 1 and 3 servers (Fig. (e): servers per "
               "request averaged over each β test steps, every such mean in [1, 3] and not all "
               "equal; one server every time does not vary)"),
    PaperClaim(2, "median_below_target", "SafeTail median below the average target latency"),
    PaperClaim(2, "oracle_tail_above_target",
               "Even Oracle's p99 exceeds the average target latency"),
    PaperClaim(2, "mean_servers_2_to_3",
               "SafeTail uses 2 to 3 servers on average and in some cases just 1 (mean servers "
               "per request in [2, 3], and at least one test request sent to one server)"),
    PaperClaim(2, "beats_minprop3_tails",
               "SafeTail outperformed MinProp-3 in the cases other than the median (faster at "
               "p90, p95 and p99)"),
    PaperClaim(3, "mostly_1_to_2_servers",
               "SafeTail uses mostly 1 to 2 servers, and not always the same number (\"utilized "
               "1-3 edge servers\": median servers per request <= 2, and Fig. (e)'s β-step "
               "means not all equal)"),
    PaperClaim(3, "baseline_better_p50_p90",
               "The baselines outperform SafeTail at median and p90 (\"the baseline methods\": "
               "more than half of the Rand/MinLoad/MinProp baselines run are faster at each, "
               "the same quantifier as at p95 and p99)"),
    PaperClaim(3, "safetail_better_p95_p99",
               "SafeTail outperforms the baselines at p95 and p99 (faster than more than half "
               "of the Rand/MinLoad/MinProp baselines run at each, the same quantifier as at "
               "median and p90)"),
    PaperClaim(3, "below_target_p50_p90",
               "SafeTail's median and p90 below the average target latency"),
)


#: The methods whose ratios with SafeTail in use case 1 form the calibration subset: the
#: sixteen numbers whose combination (each x = 1 baseline's latency over Oracle's)
#: ``experiments/calibrate.py`` fits the unpublished world parameters to (docs/calibration.md).
#: Every other stated number is held out: no fit consumes it. (Once one did: rule 6 chose
#: UC3's compute scale from UC3's bounds at 7a364ea, taken back at 3fa44db; docs/calibration.md.)
CALIBRATION_REFERENCES: tuple[str, ...] = ("Rand-1", "MinLoad-1", "MinProp-1", ORACLE)


def in_calibration_subset(ratio: PaperRatio) -> bool:
    """Whether ``ratio`` is one of the sixteen calibration numbers (use case 1: SafeTail against
    the x = 1 baselines and against Oracle, in whichever direction the paper states it)."""
    other = ratio.reference if ratio.method == SAFETAIL else ratio.method
    return (ratio.use_case == 1 and SAFETAIL in (ratio.method, ratio.reference)
            and other in CALIBRATION_REFERENCES)


CALIBRATION_RATIOS: tuple[PaperRatio, ...] = tuple(r for r in PAPER_RATIOS if in_calibration_subset(r))


def paper_speedup(use_case: int, method: str, reference: str, percentile: int) -> float | None:
    """The paper's speed-up of ``method`` over ``reference``, converting direction if needed.

    Args:
        use_case: 1, 2 or 3.
        method: e.g. "Oracle" or "SafeTail".
        reference: e.g. "SafeTail" or "Rand-1".
        percentile: 50, 90, 95 or 99.

    Returns:
        ``latency(reference) / latency(method)`` as the paper states it, or None when the paper
        states no such number.
    """
    for ratio in PAPER_RATIOS:
        if (ratio.use_case, ratio.percentile) != (use_case, percentile):
            continue
        if (ratio.method, ratio.reference) == (method, reference):
            return ratio.speedup
        if (ratio.method, ratio.reference) == (reference, method):
            return 1.0 / ratio.speedup
    return None


def paper_statement(use_case: int, method: str, reference: str, percentile: int) -> str | None:
    """The wording of the paper's statement behind :func:`paper_speedup`, or None."""
    for ratio in PAPER_RATIOS:
        if (ratio.use_case, ratio.percentile) == (use_case, percentile) and {
            ratio.method,
            ratio.reference,
        } == {method, reference}:
            return ratio.stated
    return None


# --------------------------------------------------------------------------------------------
# Whether a run is in the paper's setting (its closeness to the paper is scored only then)


def _is_file(recorded: str, expected: Path) -> bool:
    """Whether the path ``run.json`` recorded is ``expected`` (a relative path is the
    project's: run.json records files inside the project relative to it)."""
    path = Path(recorded)
    if not path.is_absolute():
        path = REPOSITORY / path
    return path.resolve() == expected.resolve()


def _project_path(path: Path) -> str:
    return path.relative_to(REPOSITORY).as_posix()


def setting_differences(run: RunMetadata) -> list[str]:
    """How ``run``'s setting departs from the paper's, one phrase each; empty when it does not.

    The paper's setting is its five-server topology with its placement (§V-A) and a world that
    is one of this project's readings of the paper's (``landed``, the ``paper-literal``
    preset's, or ``calibrated``, the others'; ``edge/calibration.py``) with none of its settings
    changed by the run's own options (``--target-latency-s``, ``--load-peak-users``,
    ``--target-compute``: ``run.json``'s ``world_overrides``). The preset and the learner (e.g.
    ``--learning-rate``) are not the setting but what is compared in it, and the number of
    requests is :func:`files.thin_percentiles`'s business. A ``run.json`` written before the
    placement or the overrides were recorded is taken at its word on what it does record; a
    fixed target latency is seen in its ``world`` whatever its age (no preset world has one).

    Args:
        run: the run's metadata (``run.json``).

    Returns:
        Phrases such as ``topology topologies/3servers.json (the paper's:
        topologies/paper_5servers.json)`` or ``--load-peak-users 2.0``.
    """
    out = []
    if not _is_file(run.topology, DEFAULT_TOPOLOGY):
        out.append(f"topology {run.topology} (the paper's: {_project_path(DEFAULT_TOPOLOGY)})")
    placement = run.extra.get(PLACEMENT_KEY)
    if isinstance(placement, str) and not _is_file(placement, DEFAULT_PLACEMENT):
        out.append(f"placement {placement} (the paper's: {_project_path(DEFAULT_PLACEMENT)})")
    world = run.extra.get("world")
    world = world if isinstance(world, dict) else {}
    name = world.get("name")
    if name is not None and name not in WORLD_NAMES:
        out.append(f"world {name!r} (the presets' readings of the paper's: {', '.join(WORLD_NAMES)})")
    overrides = run.extra.get(WORLD_OVERRIDES_KEY)
    overrides = overrides if isinstance(overrides, dict) else {}
    out.extend(f"--{option.replace('_', '-')} {value}" for option, value in sorted(overrides.items()))
    fixed = world.get("target_latency_s")
    if fixed is not None and "target_latency_s" not in overrides:
        out.append(f"a fixed target latency of {fixed} s (the paper's τ is Eq. 4's, per request)")
    return out


# --------------------------------------------------------------------------------------------
# Our ratios and claims beside the paper's


SPEEDUP_COLUMNS: tuple[str, ...] = (
    "method", "reference", "percentile", "ours", "paper", "stated",
)


def speedup_table(summary: pd.DataFrame, use_case: int | None) -> pd.DataFrame:
    """The ratios the paper quotes, ours next to the paper's.

    Rows: Oracle over SafeTail at each percentile (``ours`` = SafeTail latency / Oracle
    latency, the paper's "Oracle ... 1.08x faster"), then SafeTail over each Rand/MinLoad/
    MinProp baseline present at each percentile (``ours`` = baseline latency / SafeTail
    latency). ``paper`` is the paper's number in the same direction (converted when the paper
    states the reciprocal; NaN where it states none) and ``stated`` its wording.

    Args:
        summary: from :func:`summarize`.
        use_case: 1, 2 or 3 to fill the paper columns; None leaves them empty.

    Returns:
        A DataFrame with columns ``SPEEDUP_COLUMNS``; empty when SafeTail is absent.
    """
    methods = list(summary["method"])
    pairs: list[tuple[str, str]] = []
    if SAFETAIL in methods:
        if ORACLE in methods:
            pairs.append((ORACLE, SAFETAIL))
        pairs.extend((SAFETAIL, baseline) for baseline in baselines_of(methods))
    rows = []
    for method, reference in pairs:
        for percentile in PERCENTILES:
            paper = None if use_case is None else paper_speedup(use_case, method, reference,
                                                                 percentile)
            stated = None if use_case is None else paper_statement(use_case, method, reference,
                                                                   percentile)
            rows.append({
                "method": method,
                "reference": reference,
                "percentile": percentile,
                "ours": speedup(summary, method, reference, percentile),
                "paper": math.nan if paper is None else paper,
                "stated": stated or "",
            })
    return pd.DataFrame(rows, columns=list(SPEEDUP_COLUMNS))


AGREE_TOLERANCE = 0.05
UNITY_TOLERANCE = 0.02


def _difference_note(mean: float, low: float, high: float, paper: float, method: str,
                     reference: str) -> str:
    if math.isnan(paper):
        return "paper states no number"
    if math.isnan(mean):
        return "not measured in these runs"
    if not math.isnan(low):
        if low <= paper <= high:
            return "consistent: paper value inside our 95% interval"
    elif abs(mean / paper - 1) <= AGREE_TOLERANCE:
        return f"close: within {AGREE_TOLERANCE:.0%} (single seed, no interval)"

    def side(value: float) -> int:
        return 0 if abs(value - 1) <= UNITY_TOLERANCE else (1 if value > 1 else -1)

    if side(mean) == side(paper):
        return f"differs in size: ours {mean:.2f} vs paper {paper:.2f}"
    faster = {1: f"{method} faster", -1: f"{reference} faster", 0: "about equal"}
    return f"differs in direction: ours {faster[side(mean)]}, paper {faster[side(paper)]}"


AGGREGATE_SPEEDUP_COLUMNS: tuple[str, ...] = (
    "use_case", "method", "reference", "percentile", "mean", "ci_low", "ci_high", "n_seeds",
    "paper", "stated", "note",
)


def aggregate_speedups(directories: Sequence[str | os.PathLike[str]]) -> pd.DataFrame:
    """The paper's ratios (see :func:`speedup_table`) per seed, then their geometric mean and a
    95% t-interval on the log scale (:func:`geometric_interval`).

    The ratio is computed within each seed first and then combined, so the interval reflects
    the seed-to-seed spread of the ratio itself. ``note`` compares with the paper: inside our
    interval ("consistent"; a wide interval makes this weak, so read it with the interval);
    with one seed, within 5% ("close"); otherwise "differs in size" when both sit on the same
    side of 1 (±2% counts as equal) and "differs in direction" when not.

    Args:
        directories: run folders of one use case, one per seed.

    Returns:
        Columns ``AGGREGATE_SPEEDUP_COLUMNS``.
    """
    runs = load_runs(directories)
    use_case = runs[0][0].use_case
    tables = [speedup_table(summary, use_case) for _, summary in runs]
    keys = pd.concat(tables)[["method", "reference", "percentile", "paper", "stated"]]
    keys = keys.drop_duplicates(["method", "reference", "percentile"])
    rows = []
    for entry in keys.itertuples(index=False):
        values = []
        for table in tables:
            match = table[(table["method"] == entry.method) & (table["reference"] == entry.reference)
                          & (table["percentile"] == entry.percentile)]
            if not match.empty:
                values.append(float(match["ours"].iloc[0]))
        mean, low, high = geometric_interval(values)
        rows.append({
            "use_case": use_case, "method": entry.method, "reference": entry.reference,
            "percentile": entry.percentile, "mean": mean, "ci_low": low, "ci_high": high,
            "n_seeds": len([v for v in values if not math.isnan(v)]), "paper": entry.paper,
            "stated": entry.stated,
            "note": _difference_note(mean, low, high, entry.paper, entry.method, entry.reference),
        })
    return pd.DataFrame(rows, columns=list(AGGREGATE_SPEEDUP_COLUMNS))
