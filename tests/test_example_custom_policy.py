"""The custom-policy example runs, respects Oracle's per-request lower bound, and is visibly a
policy of its own: its numbers are no baseline's."""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np

from yafs_safetail.edge.calibration import world_settings
from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, load_inputs
from yafs_safetail.methods import make_baseline
from yafs_safetail.methods.registry import CONTENTION_BASELINES, baseline_names
from yafs_safetail.sim.runner import simulate

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "custom_policy" / "nearest_free.py"
SHOWN = ("NearestFree", "MinProp-1", "MinProp-2", "Oracle")


def test_custom_policy_example_runs_on_common_random_numbers() -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "custom_policy" / "main.py"), "--steps", "200"],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    rows = {}
    for line in done.stdout.splitlines():
        parts = line.split()
        if parts and parts[0] in SHOWN:
            rows[parts[0]] = [float(v) for v in parts[1:]]
    assert set(rows) == set(SHOWN)
    # Same requests for every method: Oracle is below the others at every percentile.
    for name in SHOWN[:-1]:
        assert all(o <= m for o, m in zip(rows["Oracle"][:4], rows[name][:4], strict=True)), rows
    # A reader sees it ran: its percentiles are neither baseline's, and it sends one or two
    # copies per request (the last column).
    assert rows["NearestFree"][:4] not in (rows["MinProp-1"][:4], rows["MinProp-2"][:4]), rows
    assert 1 <= rows["NearestFree"][-1] <= 2 and rows["MinProp-2"][-1] == 2, rows


def test_the_example_policy_chooses_unlike_every_baseline() -> None:
    spec = importlib.util.spec_from_file_location("nearest_free_example", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    use_case = get_use_case(1)
    scenario = load_scenario(ROOT / "topologies" / "paper_5servers.json",
                             ROOT / "placements" / "paper_5servers.json")
    world = build_world(scenario, use_case, load_inputs(use_case), 200, seed=1, phase="test",
                        settings=world_settings("calibrated"))
    n = world.n_servers

    def choices(policy) -> list[tuple[int, ...]]:  # type: ignore[no-untyped-def]
        return [record.servers for record in simulate(world, policy)]

    mine = choices(module.NearestFree(n, np.random.default_rng(0)))
    for name in [*baseline_names(range(1, n + 1))]:
        assert choices(make_baseline(name, n, np.random.default_rng(0))) != mine, name
    assert set(CONTENTION_BASELINES) == {"Hedge", "Tied"}  # (hedged copies: another world)


def test_the_ten_line_policy_is_at_most_fifteen_lines_of_code() -> None:
    tree = ast.parse(EXAMPLE.read_text())
    for node in ast.walk(tree):  # drop docstrings: count code only
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) \
                and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str):
            body.pop(0)
    code = ast.unparse(tree).splitlines()
    assert 3 <= len(code) <= 15, code
