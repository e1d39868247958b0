"""``benchmarks/bench_fidelity.py``'s scorecard (issue 48): the goals judged against what the
method's own training target reaches, the lines it prints (the earlier ones kept), the JSON it
writes and the README's rendering of it. Its small-budget end-to-end run is in
``test_benchmarks.py`` (slow)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest

from yafs_safetail.results import feasibility
from yafs_safetail.results.fidelity import FIDELITY_COLUMNS
from yafs_safetail.results.paper import PAPER_CLAIMS, PAPER_RATIOS, in_calibration_subset
from yafs_safetail.runs import method_optimum as mo
from yafs_safetail.runs import most_zeros as mz

REPOSITORY = Path(__file__).resolve().parents[1]


def _script(folder: str, name: str):
    spec = importlib.util.spec_from_file_location(name, REPOSITORY / folder / f"{name}.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


bench_fidelity = _script("benchmarks", "bench_fidelity")
readme_tables = _script("tables", "readme_tables")

#: The claims that fail in the made-up runs (the rest hold).
FAILING = {"uc1 below_target_all", "uc2 median_below_target"}


def _card() -> pd.DataFrame:
    rows = [{"kind": "ratio", "use_case": r.use_case, "key": f"{r.method} over {r.reference}",
             "within_tolerance": i % 3 != 0,
             "subset": "calibration" if in_calibration_subset(r) else "held-out"}
            for i, r in enumerate(PAPER_RATIOS)]
    rows += [{"kind": "claim", "use_case": c.use_case, "key": c.key,
              "within_tolerance": f"uc{c.use_case} {c.key}" not in FAILING} for c in PAPER_CLAIMS]
    rows += [{"kind": "access_rate", "use_case": uc, "key": "access", "ours": ours, "within_tolerance": True}
             for uc, ours in ((1, 0.30), (2, 0.55), (3, 0.70))]
    return pd.DataFrame(rows).reindex(columns=list(FIDELITY_COLUMNS))


def _summary(p99_by_method: dict[str, float]) -> pd.DataFrame:
    return pd.DataFrame([{"method": m, "p90_s": p99 / 2, "p95_s": p99 / 1.5, "p99_s": p99,
                          "fallback_rate": 0.001 if m == "SafeTail" else 0.0}
                         for m, p99 in p99_by_method.items()])


def _optimum(use_case: int, access: float, median: float, windows: tuple[float, ...]) -> mo.Optimum:
    figures = mo.SeedFigures(0, 0.9, access * 5, access, median, 1, 5, windows, 1.0)
    return mo.Optimum(use_case, mz.DEFAULT_KEY, (1000,), (figures,))


@pytest.fixture()
def card() -> dict:
    # UC1, seed 0: below every baseline; seed 1: MinLoad-2 beats SafeTail at p99.
    worlds = [
        SimpleNamespace(use_case=1, seed=0, summary=_summary({"SafeTail": 2.0, "Rand-1": 7.0, "MinLoad-2": 4.0})),
        SimpleNamespace(use_case=1, seed=1, summary=_summary({"SafeTail": 2.0, "Rand-1": 7.0, "MinLoad-2": 1.9})),
        SimpleNamespace(use_case=2, seed=0, summary=_summary({"SafeTail": 2.0, "Rand-1": 7.0})),
        SimpleNamespace(use_case=3, seed=0, summary=_summary({"SafeTail": 2.0, "Rand-1": 7.0})),
    ]
    comparisons = {
        1: mo.Comparison(1, (mo.SafeTailFigures(0, 0.88, 1.5, 0.30),), _optimum(1, 0.26, 1, (1.0, 2.5))),
        # UC2: the policy's own access is above 0.5, so that goal is out of the method's reach.
        2: mo.Comparison(2, (mo.SafeTailFigures(0, 0.80, 2.75, 0.55),), _optimum(2, 0.52, 2, (2.0, 3.0))),
        # UC3: the policy's median is 3 servers, so "mostly 1 to 2" is out of the method's reach.
        3: mo.Comparison(3, (mo.SafeTailFigures(0, 0.85, 3.5, 0.70),), _optimum(3, 0.60, 3, (2.5, 3.5))),
    }
    top = feasibility.Ceiling(20, 21, 23, 10, 11, ("uc3 below_target_p50_p90",))
    about = {"preset": "paper", "seeds": [7400, 7401, 7402, 7403, 7404], "steps_scale": 1.0,
             "commit": "0123456789abcdef", "command": "python benchmarks/bench_fidelity.py --from OUT"}
    return bench_fidelity.assemble(_card(), top, worlds, comparisons, about)


def test_claims_the_method_cannot_reach_are_reported_with_the_policy_s_figure(card):
    claims = card["goals"]["reachable_claims"]
    (missed,) = claims["not_reachable_by_the_method"]
    assert (missed["use_case"], missed["key"]) == (3, "mostly_1_to_2_servers")
    assert missed["policy"] == "median 3 servers, β-window means 2.50–3.50"
    assert claims["not_reachable_by_any_policy"] == ["uc3 below_target_p50_p90"]
    # 11 claims less one out of any policy's reach and one out of the method's; two fail.
    assert (claims["measured"], claims["of"]) == (7, 9) and claims["verdict"] == bench_fidelity.MISSED
    assert sorted(claims["not_holding"]) == sorted(FAILING)


def test_the_access_goals_are_judged_against_the_method_s_optimum(card):
    access = card["goals"]["access"]
    assert access["measured"]["1"]["verdict"] == bench_fidelity.MET
    assert access["measured"]["2"]["verdict"] == bench_fidelity.NOT_REACHABLE
    assert "3" not in access["measured"] and access["verdict"] == bench_fidelity.MET
    gaps = card["goals"]["access_vs_method"]
    assert gaps["measured"]["1"] == pytest.approx(0.04) and gaps["measured"]["3"] == pytest.approx(0.10)
    assert gaps["verdict"] == bench_fidelity.MISSED  # UC3: 0.10 above the policy's
    zeros = card["goals"]["zero_share"]
    assert zeros["measured"]["2"] == pytest.approx(-0.10) and zeros["verdict"] == bench_fidelity.MISSED


def test_uc1_tails_are_counted_against_x_1_and_against_x_1_2_3(card):
    goals = card["goals"]
    assert (goals["uc1_tails"]["measured"], goals["uc1_tails"]["of"]) == (2, 2)
    assert (goals["uc1_tails_x123"]["measured"], goals["uc1_tails_x123"]["of"]) == (1, 2)


def test_the_printed_lines_keep_the_earlier_ones_in_their_order(card):
    lines = bench_fidelity.card_lines(card)
    names = [line.split("=", 1)[0] for line in lines]
    earlier = ["ratios_within_20", "held_out_within_20", "calibration_within_20", "claims_hold",
               "reachable_claims_hold", "access_rate_uc1", "access_rate_uc2", "access_rate_uc3",
               "safetail_fallback_max", "uc1_tails_below_x1_seeds", "x1_p95_at_fallback_seeds",
               "goals_met", "any_policy_ratios_at_most", "any_policy_claims_at_most"]
    assert names[:len(earlier)] == earlier
    figures = dict(line.split("=", 1) for line in lines)
    assert figures["reachable_claims_hold"] == "7/9"
    assert [goal.split(":")[0] for goal in figures["goals_met"].split(",")] == [
        "ratios", "reachable_claims", "access", "fallback", "uc1_tails", "x1_p95_not_fallback",
        "uc1_tails_x123", "access_vs_method", "zero_share"]
    assert figures["uc1_tails_below_x123_seeds"] == "1/2"
    assert figures["access_goal_uc2"] == "not reachable by the method here (most zeros: 0.520)"
    assert figures["not_reachable_by_method"].startswith("uc3:mostly_1_to_2_servers (median 3")
    assert figures["zero_share_gap_uc1"] == "-0.020"


def test_the_written_json_renders_as_the_readme_s_scorecard(card, tmp_path):
    path = tmp_path / "scorecard.json"
    path.write_text(bench_fidelity.card_json(card), encoding="utf-8")
    table = readme_tables.scorecard_block(readme_tables.read_scorecard(path))
    assert json.loads(path.read_text(encoding="utf-8")) == card
    assert "| 0.30 / 0.55 (its training target's best: 0.52) | met |" in table
    assert "| 0.30 vs 0.26 / 0.55 vs 0.52 / 0.70 vs 0.60 | missed |" in table
    assert ("| Use case 3: “SafeTail uses mostly 1 to 2 servers, and not always the same number” | "
            "the best policy for SafeTail's own training target: median 3 servers, β-window means "
            "2.50–3.50 | not reachable by the method here |") in table
    assert "| 1 of 2 seeds | missed |" in table and "Seeds 7400–7404, preset `paper`, commit 0123456" in table
    for jargon in ("rule ", "D17", "x1", "uc1"):
        assert jargon not in table


def test_a_placeholder_scorecard_is_refused_in_one_line(tmp_path):
    path = tmp_path / "scorecard.json"
    path.write_text('{"placeholder": true}\n', encoding="utf-8")
    with pytest.raises(SystemExit, match="not a scorecard .*--write docs/scorecard.json"):
        readme_tables.read_scorecard(path)


def test_a_folder_missing_a_use_case_s_runs_is_named(tmp_path):
    for use_case in (1, 2):
        (tmp_path / f"uc{use_case}-paper" / "seed0").mkdir(parents=True)
    (tmp_path / "uc3-paper" / "seed1").mkdir(parents=True)
    with pytest.raises(bench_fidelity.ScorecardError, match=r"uc3-paper/seed0: expected the runs of seeds \[0\]"):
        bench_fidelity.folder_seeds(tmp_path, "paper", None)
    with pytest.raises(bench_fidelity.ScorecardError, match="uc3-paper/seed0"):
        bench_fidelity.folder_seeds(tmp_path, "paper", [0])
