"""Whether the paper's qualitative claims (``paper.PAPER_CLAIMS``) hold in one run's summary.

``paper.py`` holds what the paper states; this module reads a run against its claims, each
with the reading written into the claim's text (docs/results.md, "The paper's claims and how
they are read").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import pandas as pd

from yafs_safetail.methods.registry import ORACLE, SAFETAIL, baselines_of, parse_method
from yafs_safetail.results.files import PERCENTILES
from yafs_safetail.results.paper import MINPROP_3, PAPER_CLAIMS
from yafs_safetail.results.stats import speedup


def more_than_half(flags: Sequence[bool]) -> bool:
    """Whether more than half of ``flags`` are true (False for none): the quantifier of UC3's
    "the baseline methods outperformed SafeTail" and "SafeTail performed better" alike."""
    return 2 * sum(flags) > len(flags)


def _server_range(safetail: pd.Series) -> tuple[float, float]:
    """The smallest and largest mean servers per request over Fig. (e)'s β-step windows; for a
    summary written before those columns, the smallest and largest of single requests."""
    low, high = float(safetail["min_window_n_selected"]), float(safetail["max_window_n_selected"])
    if math.isnan(low):
        low, high = float(safetail["min_n_selected"]), float(safetail["max_n_selected"])
    return low, high


def _ratios_over(summary: pd.DataFrame, references: Sequence[str], percentile: int) -> list[float]:
    """SafeTail's speed-up over each reference at ``percentile``; references without a latency
    there are left out (not run), so none is counted as beaten or as faster."""
    values = [speedup(summary, SAFETAIL, r, percentile) for r in references]
    return [v for v in values if not math.isnan(v)]


def _claim_holds(key: str, summary: pd.DataFrame) -> bool | None:
    methods = list(summary["method"])
    if SAFETAIL not in methods:
        return None
    safetail = summary[summary["method"] == SAFETAIL].iloc[0]
    target = float(safetail["mean_target_s"])
    baselines = baselines_of(methods)

    def below_target(percentiles: Sequence[int]) -> bool | None:
        values = [float(safetail[f"p{p}_s"]) for p in percentiles]
        if math.isnan(target) or any(math.isnan(v) for v in values):
            return None
        return all(v < target for v in values)

    def at_each(percentiles: Sequence[int], references: Sequence[str],
                test: Callable[[list[float]], bool]) -> bool | None:
        """``test`` of SafeTail's speed-ups over ``references`` at every percentile; None when
        some percentile has none to test (a needed method is absent)."""
        ratios = [_ratios_over(summary, references, p) for p in percentiles]
        if not all(ratios):
            return None
        return all(test(r) for r in ratios)

    if key == "below_target_all":
        return below_target(PERCENTILES)
    if key == "median_below_target":
        return below_target((50,))
    if key == "below_target_p50_p90":
        return below_target((50, 90))
    if key == "servers_1_to_3":
        low, high = _server_range(safetail)
        # "Varies": a policy that sends the same number of servers every time has all its
        # windows equal and does not pass on the bounds alone.
        return 1 <= low < high <= 3
    if key == "mean_servers_2_to_3":
        # "In some cases, just 1 edge server": some request went to one server (the fewest
        # any request can go to), so a policy that always sends 2 or 3 does not pass.
        return 2.0 <= float(safetail["mean_n_selected"]) <= 3.0 and int(safetail["min_n_selected"]) == 1
    if key == "mostly_1_to_2_servers":
        low, high = _server_range(safetail)
        # "Utilized 1-3 edge servers": the count varies, so one server every time, which is
        # "mostly 1 to 2" to the letter, does not pass.
        return float(safetail["median_n_selected"]) <= 2.0 and low < high
    if key == "oracle_tail_above_target":
        if ORACLE not in methods:
            return None
        oracle = summary[summary["method"] == ORACLE].iloc[0]
        return float(oracle["p99_s"]) > float(oracle["mean_target_s"])
    if key == "beats_x23_all":
        higher = [b for b in baselines if parse_method(b)[1] in (2, 3)]
        return at_each(PERCENTILES, higher, lambda r: all(v > 1 for v in r))
    if key == "beats_minprop3_tails":
        return at_each((90, 95, 99), [MINPROP_3], lambda r: all(v > 1 for v in r))
    if key == "baseline_better_p50_p90":
        return at_each((50, 90), baselines, lambda r: more_than_half([v < 1 for v in r]))
    if key == "safetail_better_p95_p99":
        return at_each((95, 99), baselines, lambda r: more_than_half([v > 1 for v in r]))
    raise KeyError(f"no check for paper claim {key!r}")


def claim_holds(key: str, summary: pd.DataFrame) -> bool | None:
    """Whether the paper's claim ``key`` holds in a summary (one row per method, SafeTail's
    among them; the columns the claim reads): True, False, or None when it cannot be checked
    (a needed method is absent). ``runs.method_optimum`` reads a learner-free policy's
    decisions through it, in SafeTail's row.

    Raises:
        KeyError: no check for ``key``.
    """
    return _claim_holds(key, summary)


def check_claims(summary: pd.DataFrame, use_case: int) -> pd.DataFrame:
    """The paper's qualitative statements for ``use_case`` and whether this run bears them out.

    Returns:
        Columns ``key, text, holds`` with ``holds`` True, False or None (cannot be checked:
        a needed method is absent).
    """
    claims = [c for c in PAPER_CLAIMS if c.use_case == use_case]
    return pd.DataFrame({
        "key": pd.Series([c.key for c in claims], dtype=object),
        "text": pd.Series([c.text for c in claims], dtype=object),
        # object dtype keeps True/False/None as they are (no coercion to numpy bools or NaN).
        "holds": pd.Series([_claim_holds(c.key, summary) for c in claims], dtype=object),
    })
