"""The README's tables of figures are what their commands give (issue 39): the first table against
a fresh default run of use case 1 with the locked library versions, the scorecard against the
committed ``docs/scorecard.json`` (issue 48), every marked table against its renderer.
``tables/readme_tables.py --write`` rewrites them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from in_process import run_usecase_here

from yafs_safetail import versions

REPOSITORY = Path(__file__).resolve().parents[1]


def _readme_tables():
    spec = importlib.util.spec_from_file_location("readme_tables", REPOSITORY / "tables" / "readme_tables.py")
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
        "rewrite it with `python tables/readme_tables.py --write`")


def test_a_table_is_replaced_between_its_markers_only():
    text = ("a\n<!-- readme_tables: timing -->\nold\n<!-- /readme_tables -->\nb\n"
            "<!-- readme_tables: scorecard -->\nkeep\n<!-- /readme_tables -->\n")
    new = readme_tables.replaced(text, "timing", "new\n")
    assert readme_tables.readme_blocks(new) == {"timing": "new\n", "scorecard": "keep\n"}
    assert new.startswith("a\n") and "\nb\n" in new


def _committed_scorecard() -> dict:
    try:
        return readme_tables.read_scorecard()
    except SystemExit as error:  # missing or a placeholder: say how to write it
        pytest.fail(str(error))


def test_the_readme_scorecard_is_the_committed_scorecard():
    readme = readme_tables.readme_blocks((REPOSITORY / "README.md").read_text(encoding="utf-8"))
    assert readme["scorecard"] == readme_tables.scorecard_block(_committed_scorecard()), (
        "README.md's scorecard is not docs/scorecard.json's; rewrite it with "
        "`python tables/readme_tables.py --write --only scorecard`")


def test_the_committed_scorecard_is_the_latest_held_out_set_at_full_budget():
    from yafs_safetail.edge.calibration import seed_set

    card = _committed_scorecard()
    # seed_sets.json's method_held_out: read by nothing before issue 48's default was reported.
    assert card["seeds"] == seed_set(readme_tables.SCORECARD_SEED_SET)
    assert (card["preset"], card["steps_scale"]) == ("paper", 1.0)


def _summary(p_s: dict[str, float]):
    import pandas as pd

    return pd.DataFrame([{"method": m, "p90_s": v, "p95_s": v, "p99_s": v} for m, v in p_s.items()]
                        ).set_index("method")


def test_the_first_tables_sentence_compares_safetail_with_every_x_1_2_3_baseline():
    faster = _summary({"SafeTail": 1.0, "Oracle": 0.9, "Rand-1": 3.0, "MinLoad-1": 1.5,
                       "Rand-2": 1.4, "MinProp-2": 2.0, "MinLoad-3": 1.25})
    assert readme_tables.tails_sentence(faster) == (
        "At p90, p95 and p99 it is faster than every baseline, by at least 1.50× those that send "
        "each request to one server, 1.40× those that send it to two and 1.25× those that send it to three.")
    slower = _summary({"SafeTail": 1.0, "Oracle": 0.9, "Rand-1": 2.0, "MinLoad-3": 0.8})
    assert readme_tables.tails_sentence(slower) == (
        "At p90, p95 and p99 it is slower than MinLoad-3 at p90 (1.25×); faster by 2.00× those "
        "that send each request to one server.")


def test_the_least_loaded_table_counts_the_seeds_each_beats_safetail_in():
    spec = importlib.util.spec_from_file_location("least_loaded", REPOSITORY / "tables" / "least_loaded.py")
    assert spec and spec.loader
    least_loaded = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(least_loaded)
    import pandas as pd

    def run(safetail_p99: float) -> pd.DataFrame:
        rows = [("SafeTail", 1.5, 1.0, safetail_p99), ("MinLoad-1", 1.0, 1.1, 2.5),
                ("MinLoad-2", 2.0, 0.9, 2.0), ("MinLoad-3", 3.0, 0.8, 1.5)]
        return pd.DataFrame(rows, columns=["method", "mean_n_selected", "p50_s", "p99_s"]).set_index("method")

    lines = least_loaded.table({1: [run(2.2), run(1.8)]})
    assert lines[2] == ("| 1 | 1.50, 1.000, 2.000 | 1.100, 2.500; median 0, p99 0 of 2 | "
                        "0.900, 2.000; median 2, p99 1 of 2 | 0.800, 1.500; median 2, p99 2 of 2 |")
