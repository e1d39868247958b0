"""A campaign ends with the latency of what it ran over seeds, grouped by its other axes."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from in_process import run_in_process

from yafs_safetail.results.seed_tables import grouping_axes, user_methods

GRID = """
[base]
use_case = 1
steps_scale = 0.013
figures = false
[axes]
redundancy_levels = [[1], [2]]
seed = [0, 1]
"""


def test_the_axes_that_group_are_those_that_vary_but_the_seed() -> None:
    settings = {"a": {"use_case": 1, "preset": "paper", "seed": 0, "methods": ["x.py:X"]},
                "b": {"use_case": 1, "preset": "tuned", "seed": 1, "methods": ["x.py:X"]},
                "c": {"use_case": 2, "preset": "paper", "seed": 0, "methods": ["x.py:X"]}}
    assert grouping_axes(settings) == ["use_case", "preset"]
    assert grouping_axes({"a": {"seed": 0}, "b": {"seed": 1}}) == []
    assert user_methods(["Rand-2", "Mine", "SafeTail", "Oracle", "Tied", "Alpha"]) == ["Alpha", "Mine"]


def test_a_campaign_ends_with_latency_over_seeds_per_setting(tmp_path: Path) -> None:
    from yafs_safetail import results
    from yafs_safetail.commands import campaign

    grid = tmp_path / "grid.toml"
    grid.write_text(GRID)
    out = tmp_path / "c"
    done = run_in_process(campaign.main, "--grid", grid, "--out", out)
    assert done.returncode == 0, done.stderr[-2000:]
    # Printed and written alike (then the folder): one table per redundancy setting, each over
    # both seeds.
    text = (out / "latency.md").read_text()
    assert done.stdout == f"{text}results: {out}\n"
    assert text.count("## redundancy_levels=") == 2 and text.count("(seeds 0, 1)") == 2
    table = pd.read_csv(out / "latency.csv")
    assert set(table["redundancy_levels"]) == {"[1]", "[2]"} and table["n_seeds"].eq(2).all()
    level_one = table[table["redundancy_levels"] == "[1]"]
    assert "Rand-1" in set(level_one["method"]) and "Rand-2" not in set(level_one["method"])
    # Each cell is the mean over the group's two runs, inside its bootstrap interval.
    folders = sorted(p.parent for p in out.glob("*/summary.csv") if "redundancy_levels-_1_" in p.parent.name)
    assert len(folders) == 2
    per_seed = [results.read_summary_csv(f).set_index("method").loc["SafeTail"] for f in folders]
    safetail = level_one.set_index("method").loc["SafeTail"]
    for metric in ("p50_s", "p99_s", "mean_n_selected"):
        mean = sum(s[metric] for s in per_seed) / 2
        assert abs(safetail[metric] - mean) < 1e-9
        assert safetail[f"{metric}_low"] <= mean <= safetail[f"{metric}_high"]
        assert min(s[metric] for s in per_seed) <= safetail[f"{metric}_low"]
    assert f"| SafeTail | 2 | {safetail['p50_s']:.3f} [" in text
