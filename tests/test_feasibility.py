"""What any policy could reach in a world, on hand-made worlds: the floor, the ±20% intervals of
the published ratios, the claims as bounds, the fewest statements to give up, the ceilings."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from yafs_safetail.results import feasibility
from yafs_safetail.results.feasibility import Bound, WorldRun
from yafs_safetail.results.files import PERCENTILES
from yafs_safetail.results.paper import PAPER_CLAIMS, PAPER_RATIOS

#: SafeTail's latencies at which every published use-case-1 ratio is exact.
SAFETAIL_S = {50: 1.0, 90: 2.0, 95: 2.5, 99: 3.0}
BELOW_TARGET = "claim: below the average target at every percentile"


def exact_world(seed: int = 0, target_s: float = 10.0) -> WorldRun:
    """Use case 1: Oracle and the x = 1 baselines placed so that every paper ratio holds exactly
    when SafeTail's percentiles are ``SAFETAIL_S``; the floor is Oracle's percentiles."""
    latency: dict[str, dict[int, float]] = {}
    for ratio in PAPER_RATIOS:
        if ratio.use_case != 1:
            continue
        if ratio.method == "SafeTail":  # speed-up = latency(reference) / latency(SafeTail)
            latency.setdefault(ratio.reference, {})[ratio.percentile] = (
                ratio.speedup * SAFETAIL_S[ratio.percentile])
        else:  # Oracle over SafeTail
            latency.setdefault(ratio.method, {})[ratio.percentile] = (
                SAFETAIL_S[ratio.percentile] / ratio.speedup)
    summary = pd.DataFrame([{"method": m, **{f"p{p}_s": v for p, v in by_p.items()},
                             "mean_target_s": target_s} for m, by_p in latency.items()])
    return WorldRun(1, seed, summary, dict(latency["Oracle"]))


def test_the_papers_own_numbers_can_hold_together_and_safetails_values_lie_inside():
    world = exact_world()
    checked = feasibility.check(world)
    assert checked["feasible"].all() and (checked["give_up"] == "").all()
    for row in checked.itertuples(index=False):
        assert row.low_s <= SAFETAIL_S[row.percentile] <= row.high_s
    assert feasibility.ratio_ceiling(world) == (16, 16)
    assert feasibility.claims_reachable(world) == {
        "below_target_all": True, "beats_x23_all": None, "servers_1_to_3": None}
    top = feasibility.ceiling([world])
    assert (top.ratios_low, top.ratios_high, top.ratios_total) == (16, 16, 16)
    assert (top.claims, top.claims_total, top.unreachable) == (3, 3, ())
    assert top.unbounded == ("uc1 servers_1_to_3",)  # counted as reachable, and named


def test_ratio_intervals_by_hand():
    bounds = {b.statement: b for b in feasibility.bounds(exact_world())}
    rand = bounds["SafeTail over Rand-1 p90 = 2.64 ±20%"]
    # Rand-1's p90 is 2.64 x 2 s; SafeTail's p90 must keep the ratio within [0.8, 1.2] x 2.64.
    assert (rand.low_s, rand.high_s) == pytest.approx((2.0 / 1.2, 2.0 / 0.8))
    oracle = bounds["Oracle over SafeTail median = 1.08 ±20%"]
    # Oracle's median is 1 / 1.08 s; SafeTail / Oracle within [0.8, 1.2] x 1.08.
    assert (oracle.low_s, oracle.high_s) == pytest.approx((0.8, 1.2))
    assert oracle.kind == "ratio" and bounds[BELOW_TARGET].kind == "claim"


def test_a_target_below_oracles_tail_is_out_of_reach_for_every_policy():
    # Oracle's p95 is 0.92 x 2.5 = 2.3 s and its p99 0.79 x 3 = 2.37 s: above a 1.9 s target;
    # its p90 (1.86 s) is not.
    world = exact_world(target_s=1.9)
    checked = feasibility.check(world).set_index("percentile")
    assert list(checked["feasible"]) == [True, True, False, False]
    assert checked.loc[95, "low_statement"].startswith("floor")
    assert checked.loc[95, "high_statement"] == BELOW_TARGET
    # Giving up the claim alone reconciles the rest (the ratios still meet at SafeTail's values).
    assert checked.loc[95, "give_up"] == BELOW_TARGET and checked.loc[99, "give_up"] == BELOW_TARGET
    assert feasibility.claims_reachable(world)["below_target_all"] is False
    assert feasibility.ratio_ceiling(world) == (16, 16)  # claims are not part of the ratio ceiling
    # In two seeds of three: out of reach (most seeds), and the report says so.
    worlds = [exact_world(0, 1.9), exact_world(1, 1.9), exact_world(2)]
    top = feasibility.ceiling(worlds)
    assert top.unreachable == ("uc1 below_target_all",) and top.claims == 2
    table = feasibility.by_percentile(feasibility.check_all(worlds)).set_index("percentile")
    assert table.loc[95, "reachable_seeds"] == 1 and not table.loc[95, "reachable"]
    assert table.loc[95, "pair_seeds"] == 2 and table.loc[95, "give_up_seeds"] == 2
    assert feasibility.reachable_count(feasibility.check_all(worlds)) == (2, 4)
    text = feasibility.feasibility_markdown(feasibility.check_all(worlds))
    assert "can hold together: 2 of 4" in text and "| 1 | p95 | 5 | 1 of 3 |" in text
    assert "out of reach: uc1 below_target_all" in feasibility.ceiling_line(worlds)


def test_a_baseline_as_fast_as_oracle_leaves_no_room_for_beating_it():
    world = exact_world()
    x3 = world.summary[world.summary["method"] == "Oracle"].assign(method="MinLoad-3")
    # MinLoad-3 1% slower than Oracle at every percentile: SafeTail must lie between the two,
    # which the UC1 p99 ratio (SafeTail 0.79x Oracle, so at least 1/0.948 x Oracle) forbids.
    for p in PERCENTILES:
        x3[f"p{p}_s"] = x3[f"p{p}_s"] * 1.01
    crowded = WorldRun(1, 0, pd.concat([world.summary, x3], ignore_index=True), world.floor_s)
    checked = feasibility.check(crowded).set_index("percentile")
    assert not checked.loc[99, "feasible"]
    assert checked.loc[99, "low_statement"] == "SafeTail over Oracle p99 = 0.79 ±20%"
    assert checked.loc[99, "high_statement"] == "claim: faster than every x = 2, 3 baseline (MinLoad-3)"
    # The claim on its own is still reachable: nothing stops a policy from matching Oracle.
    assert feasibility.claims_reachable(crowded)["beats_x23_all"] is True


def test_a_baseline_that_shares_oracles_tail_cannot_be_beaten_there():
    # "Faster" is strict, as the scorecard tests it: a baseline whose p99 is Oracle's own (the
    # same request's reply from the same server) leaves no latency strictly below it.
    world = exact_world()
    summary = world.summary.copy()
    oracle = summary[summary["method"] == "Oracle"].iloc[0]
    tied = {"method": "MinLoad-2", **{f"p{p}_s": oracle[f"p{p}_s"] * 1.5 for p in PERCENTILES},
            "mean_target_s": 10.0}
    tied["p99_s"] = world.floor_s[99]
    crowded = WorldRun(1, 0, pd.concat([summary, pd.DataFrame([tied])], ignore_index=True),
                       world.floor_s)
    assert feasibility.claims_reachable(crowded)["beats_x23_all"] is False
    checked = feasibility.check(crowded).set_index("percentile")
    assert checked.loc[99, "low_s"] >= checked.loc[99, "high_s"] and not checked.loc[99, "feasible"]
    tied["p99_s"] = world.floor_s[99] * (1 + 1e-9)
    apart = WorldRun(1, 0, pd.concat([summary, pd.DataFrame([tied])], ignore_index=True),
                     world.floor_s)
    assert feasibility.claims_reachable(apart)["beats_x23_all"] is True


def _uc3_world() -> WorldRun:
    """Use case 3 with three baselines: MinLoad-2 fastest, then MinProp-3, then Rand-1."""
    summary = pd.DataFrame([
        {"method": "Oracle", "p50_s": 4.0, "p90_s": 5.0, "p95_s": 5.5, "p99_s": 6.0, "mean_target_s": 5.0},
        {"method": "MinLoad-2", "p50_s": 4.2, "p90_s": 5.4, "p95_s": 6.5, "p99_s": 7.0, "mean_target_s": 5.0},
        {"method": "MinProp-3", "p50_s": 4.6, "p90_s": 6.0, "p95_s": 7.5, "p99_s": 8.0, "mean_target_s": 5.0},
        {"method": "Rand-1", "p50_s": 6.0, "p90_s": 8.0, "p95_s": 9.0, "p99_s": 9.5, "mean_target_s": 5.0},
    ])
    return WorldRun(3, 0, summary, {50: 4.0, 90: 5.0, 95: 5.5, 99: 6.0})


def test_uc3_pair_is_read_with_one_quantifier_more_than_half_of_the_baselines():
    world = _uc3_world()
    claims = {(b.key, b.percentile): b for b in feasibility.bounds(world) if b.kind == "claim"}
    # Three baselines: more than half is two. "Most baselines faster" puts SafeTail above the
    # second fastest (MinProp-3); "faster than most" below the second slowest (MinProp-3 too).
    better = claims[("baseline_better_p50_p90", 50)]
    assert (better.low_s, better.high_s) == (4.6, math.inf) and better.strict
    assert better.statement == "claim: most baselines faster at median, p90 (MinProp-3, 2nd fastest of 3)"
    worse = claims[("safetail_better_p95_p99", 99)]
    assert (worse.low_s, worse.high_s) == (-math.inf, 8.0)
    # Not the fastest baseline (MinLoad-2: 5.4 s at p90, 6.5 s at p95), which bounded both
    # sides in the earlier reading ("some baseline faster", "faster than every baseline").
    assert claims[("baseline_better_p50_p90", 90)].low_s == 6.0
    assert claims[("safetail_better_p95_p99", 95)].high_s == 7.5


def test_the_claims_checked_since_issue_28_are_bounds_too():
    world = _uc3_world()
    claims = {(b.key, b.percentile): b for b in feasibility.bounds(world) if b.kind == "claim"}
    # UC3: median and p90 below the average target (5 s); Oracle's p90 is 5 s, so the p90
    # bound cannot be met (strictly below the floor).
    assert claims[("below_target_p50_p90", 90)].high_s == 5.0
    assert feasibility.claims_reachable(world) == {
        "mostly_1_to_2_servers": None, "baseline_better_p50_p90": True,
        "safetail_better_p95_p99": True, "below_target_p50_p90": False}
    # UC2: faster than MinProp-3 at p90, p95, p99 (its own latencies), not at the median.
    uc2 = WorldRun(2, 0, world.summary, world.floor_s)
    minprop = {b.percentile: b for b in feasibility.bounds(uc2) if b.key == "beats_minprop3_tails"}
    assert {p: b.high_s for p, b in minprop.items()} == {90: 6.0, 95: 7.5, 99: 8.0}
    assert minprop[90].statement == "claim: faster than MinProp-3 at p90, p95, p99"
    assert feasibility.claims_reachable(uc2)["beats_minprop3_tails"] is True
    without = WorldRun(2, 0, world.summary[world.summary["method"] != "MinProp-3"], world.floor_s)
    assert feasibility.claims_reachable(without)["beats_minprop3_tails"] is None


def test_every_claim_is_read_and_those_no_interval_expresses_are_named():
    for claim in PAPER_CLAIMS:
        assert feasibility.claim_kind(claim.key) in ("latency", "world", "servers")
    with pytest.raises(KeyError, match="no reading of paper claim 'new_claim'"):
        feasibility.claim_kind("new_claim")
    assert feasibility.unbounded_claims([1, 2, 3]) == (
        "uc1 servers_1_to_3", "uc2 mean_servers_2_to_3", "uc3 mostly_1_to_2_servers")
    worlds = [exact_world(0, 1.9), exact_world(1, 1.9)]
    top = feasibility.ceiling(worlds)
    assert top.unbounded == ("uc1 servers_1_to_3",)
    line = feasibility.ceiling_line(worlds)
    assert ("(out of reach: uc1 below_target_all; not expressible as a latency bound, so counted "
            "as reachable: uc1 servers_1_to_3)") in line
    text = feasibility.feasibility_markdown(feasibility.check_all(worlds))
    assert "Claims no latency interval expresses, so not part of this check: uc1 servers_1_to_3." in text


def test_the_fewest_statements_to_give_up():
    floor = Bound(50, "floor", 1.0, math.inf, "floor", "floor")
    a = Bound(50, "a", 0.0, 0.5, "ratio", "a")
    b = Bound(50, "b", 0.0, 0.6, "ratio", "b")
    c = Bound(50, "c", 0.9, 2.0, "ratio", "c")
    assert feasibility.fewest_to_give_up([floor, a, b, c]) == (a, b)
    d = Bound(50, "d", 1.5, 2.0, "ratio", "d")
    e = Bound(50, "e", 0.0, 1.8, "ratio", "e")
    assert feasibility.fewest_to_give_up([floor, a, d, e]) == (a,)
    assert feasibility.fewest_to_give_up([floor, c, d, e]) == ()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 300),
       fallback_s=st.floats(0.1, 5.0))
def test_no_policy_beats_the_floor(seed, n, fallback_s):
    # A policy's reply is one of its servers' (never faster than Oracle's, which asks them all)
    # or the fallback when all of its servers refuse, so only where some server refused.
    rng = np.random.default_rng(seed)
    oracle_s = rng.exponential(1.0, n)
    some_refused = rng.random(n) < 0.2
    choose_refusing = rng.random(n) < 0.5
    policy_s = np.where(some_refused & choose_refusing, fallback_s, oracle_s + rng.exponential(0.5, n))
    floor = feasibility.floor_percentiles(oracle_s, fallback_s, some_refused)
    looser = feasibility.floor_percentiles(oracle_s, fallback_s)  # the fallback counted everywhere
    for p in PERCENTILES:
        assert np.percentile(policy_s, p) >= floor[p] - 1e-12
        assert floor[p] >= looser[p]
    # No server ever refused: the floor is Oracle's, however fast the fallback.
    nothing = feasibility.floor_percentiles(oracle_s, 0.0, np.zeros(n, bool))
    assert nothing == {p: float(np.percentile(oracle_s, p)) for p in PERCENTILES}
    assert feasibility.floor_percentiles(oracle_s, 0.0)[50] == 0.0  # the looser floor without the mask


def test_a_floor_needs_oracles_rows():
    with pytest.raises(ValueError, match="no Oracle test rows"):
        feasibility.floor_percentiles(np.array([]), 1.0)
