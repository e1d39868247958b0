"""The README's tables of figures are what their commands give (issue 39): the first table against
a fresh default run of use case 1 with the locked library versions, every marked table against
its renderer. ``benchmarks/readme_tables.py --write`` rewrites them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from in_process import run_usecase_here

from yafs_safetail import versions

REPOSITORY = Path(__file__).resolve().parents[1]


def _readme_tables():
    spec = importlib.util.spec_from_file_location("readme_tables", REPOSITORY / "benchmarks" / "readme_tables.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


readme_tables = _readme_tables()


def test_every_marked_table_has_a_renderer_and_the_first_run_is_marked():
    blocks = readme_tables.readme_blocks((REPOSITORY / "README.md").read_text(encoding="utf-8"))
    assert {"first-run", "scorecard", "timing"} <= set(blocks)
    assert set(blocks) <= set(readme_tables.RENDERERS)


def test_the_readme_first_table_is_a_fresh_default_run(tmp_path):
    differ = versions.differences_from_lock(versions.installed_versions(), versions.locked_versions())
    if differ:
        pytest.skip(f"not the lock's library versions ({', '.join(sorted(differ))}); the README's "
                    "figures need them: pip install -c constraints.txt -e '.[dev]'")
    out = tmp_path / "uc1"
    done = run_usecase_here("--uc", "1", "--no-figures", "--quiet", "--out", out)
    assert done.returncode == 0, done.stderr[-2000:]
    readme = readme_tables.readme_blocks((REPOSITORY / "README.md").read_text(encoding="utf-8"))
    assert readme["first-run"] == readme_tables.first_run_block(out), (
        "README.md's first table is not what `python experiments/run_usecase.py --uc 1` gives; "
        "rewrite it with `python benchmarks/readme_tables.py --write`")


def test_a_table_is_replaced_between_its_markers_only():
    text = ("a\n<!-- readme_tables: timing -->\nold\n<!-- /readme_tables -->\nb\n"
            "<!-- readme_tables: scorecard -->\nkeep\n<!-- /readme_tables -->\n")
    new = readme_tables.replaced(text, "timing", "new\n")
    assert readme_tables.readme_blocks(new) == {"timing": "new\n", "scorecard": "keep\n"}
    assert new.startswith("a\n") and "\nb\n" in new


def test_the_scorecard_table_reads_the_fidelity_benchmark_lines():
    figures = {"ratios_within_20": "18/23", "held_out_within_20": "6/7", "claims_hold": "6/11",
               "reachable_claims_hold": "5/9", "any_policy_ratios_at_most": "19-21/23",
               "access_rate_uc1": "0.241", "access_rate_uc2": "0.305", "access_rate_uc3": "0.812",
               "safetail_fallback_max": "0.0010", "uc1_tails_below_x1_seeds": "4/5"}
    table = readme_tables.scorecard_block(figures)
    assert "| 18 (held out: 6 of 7) |" in table
    assert "of the 9 any policy could hold (of 11) | 5 |" in table
    assert "| 0.24 / 0.30 / 0.81 |" in table and "| 0.1% |" in table and "| 4 of 5 seeds |" in table


def test_the_scorecard_reads_the_latest_held_out_seeds():
    from yafs_safetail.edge.calibration import seed_set

    # calibration.md rule 7's set, read by nothing before the default's latest change.
    assert readme_tables.SCORECARD_SEEDS == ",".join(map(str, seed_set("target_held_out")))
