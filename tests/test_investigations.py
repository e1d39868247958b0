"""The investigations (``investigations/``: one-off measurements that back a finding in the docs)
still run at a small budget; ``tests/test_cli.py`` checks that every one answers --help."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

INVESTIGATIONS = Path(__file__).resolve().parents[1] / "investigations"
REPOSITORY = INVESTIGATIONS.parent


def test_sweep_noise_small_budget():
    done = subprocess.run(
        [sys.executable, str(INVESTIGATIONS / "bench_sweep_noise.py"), "--loads", "0.9",
         "--seeds", "0,1", "--requests", "2000"],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.strip().splitlines()
    assert [line.split()[:2] for line in lines[:-1]] == [["load=0.9", "seed=0"], ["load=0.9", "seed=1"]]
    ratios = [float(line.rsplit("ratio=", 1)[1]) for line in lines[:-1]]
    worst = float(lines[-1].removeprefix("max_abs_log_ratio="))
    assert worst == pytest.approx(max(abs(np.log(r)) for r in ratios), abs=1e-3)
    # Same tie-breaking rule up to the order of equals: the two can differ, but not by much.
    assert all(0.8 < r < 1.25 for r in ratios)


def test_target_headroom_small_budget():
    done = subprocess.run(
        [sys.executable, str(INVESTIGATIONS / "bench_target_headroom.py"),
         "--seeds", "1000", "--steps", "300"],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    verdicts = [line for line in done.stdout.splitlines() if "_implied " in line]
    assert [line.split("_")[0] for line in verdicts] == ["uc1", "uc2", "uc3"]
    # UC3's bound is facts.md's "Oracle faster by 1.50x at the median", read by the script.
    assert "p50>=1.50" in verdicts[2] and "p90>=1.14" in verdicts[2]
    assert all(line.rsplit("reachable=", 1)[1] in ("yes", "no") for line in verdicts)


def test_eq5_policies_small_budget():
    done = subprocess.run(
        [sys.executable, str(INVESTIGATIONS / "eq5_policies.py"), "--seeds", "1000", "--steps", "1000",
         "--key", "loads+input+uplink"],
        capture_output=True, text=True, cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    rows = {tuple(line.split()[:2]): dict(part.split("=") for part in line.split()[2:])
            for line in done.stdout.splitlines()}
    assert {name for _, name in rows} == {"expected_reward", "most_zeros", "best_fixed", "hindsight"}
    for use_case in ("uc1", "uc2", "uc3"):
        # Hindsight earns Eq. 5's upper bound, 0, on every request; no policy earns more.
        assert float(rows[(use_case, "hindsight")]["reward"]) == 0.0
        assert all(float(row["reward"]) <= 0.0 and 1.0 <= float(row["servers"]) <= 5.0
                   for (uc, _), row in rows.items() if uc == use_case)
        assert rows[(use_case, "best_fixed")]["top_subset"] == "1.00"
    for args, named in ((("--steps", "10"), "--steps"), (("--key", "speed"), "--key")):
        bad = subprocess.run([sys.executable, str(INVESTIGATIONS / "eq5_policies.py"), *args],
                             capture_output=True, text=True, cwd=REPOSITORY, timeout=60)
        assert bad.returncode == 2 and named in bad.stderr


@pytest.mark.parametrize("folder", ["benchmarks", "investigations", "tables"])
def test_every_script_has_one_line_in_its_folders_readme(folder):
    rows = [line for line in (REPOSITORY / folder / "README.md").read_text(encoding="utf-8").splitlines()
            if line.startswith("| `")]
    named = [row.split("`")[1] for row in rows]
    assert sorted(named) == sorted(path.name for path in (REPOSITORY / folder).glob("*.py"))
    if folder == "investigations":  # an investigation says which doc cites it
        cited = [row.rstrip(" |").rsplit("|", 1)[1] for row in rows]
        assert all("docs/" in cell or "README.md" in cell for cell in cited), cited
