"""The Stable-Baselines3 example runs end to end on a tiny budget, prints a comparable table, and
prints the same table twice for the same seed. Skipped without the rl extra."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="the rl extra (pip install -e '.[rl]') is not installed")

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "examples" / "sb3_agent.py"
# UC1 at 2 % (the least that gives SafeTail a training round, κ = 128): SafeTail trains on 200
# requests, everyone is tested on the same 80; the agent trains on 300 (past the training
# world's 200: the environment draws the next world itself).
TINY = ["--uc", "1", "--seed", "5", "--steps-scale", "0.02", "--timesteps", "300"]
HEADER = ("method", "p50_s", "p90_s", "p95_s", "p99_s", "servers", "met_target")


def start(*extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, str(SCRIPT), *TINY, *extra], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def table(run: subprocess.Popen[str]) -> dict[str, list[float]]:
    """The printed table's rows by method (the wall-time line, which varies, is left out)."""
    stdout, stderr = run.communicate(timeout=300)
    assert run.returncode == 0, stderr[-2000:]
    lines = stdout.splitlines()
    start_row = next(i for i, line in enumerate(lines) if tuple(line.split()) == HEADER) + 1
    rows = {}
    for line in lines[start_row:]:
        if line.startswith("wall time"):
            break
        method, *values = line.split()
        rows[method] = [float(v) for v in values]
    return rows


def test_dqn_and_safetail_rows_are_sane_and_a_seed_repeats_its_table() -> None:
    # The two runs go side by side: most of each is TensorFlow's import and SafeTail's training.
    first, second = start("--algo", "dqn"), start("--algo", "dqn")
    rows = table(first)
    assert {"SB3-DQN", "SafeTail"} <= set(rows)
    for method in ("SB3-DQN", "SafeTail"):
        *latencies_s, servers, met_target = rows[method]
        assert all(math.isfinite(v) and v > 0 for v in latencies_s), rows[method]
        assert latencies_s == sorted(latencies_s), rows[method]  # p50 <= p90 <= p95 <= p99
        assert 1 <= servers <= 5 and 0 <= met_target <= 1, rows[method]
    # Same requests for every method: nobody beats Oracle's per-request bound at the median.
    assert rows["Oracle"][0] <= min(rows["SB3-DQN"][0], rows["SafeTail"][0])
    assert table(second) == rows


@pytest.mark.slow  # another half minute; the DQN runs above cover the shared code
def test_ppo_runs() -> None:
    rows = table(start("--algo", "ppo"))
    assert all(math.isfinite(v) and v > 0 for v in rows["SB3-PPO"][:4]), rows


def test_without_stable_baselines3_it_says_how_to_install_it_and_exits_2() -> None:
    # sys.modules[name] = None makes that import fail, as if the package were not installed
    # (torch too, which also spares this test its import).
    code = ("import runpy, sys; sys.modules['torch'] = sys.modules['stable_baselines3'] = None; "
            f"sys.argv = [{str(SCRIPT)!r}]; runpy.run_path({str(SCRIPT)!r}, run_name='__main__')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert done.returncode == 2
    assert "pip install -e '.[rl]'" in done.stderr
