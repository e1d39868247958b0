"""A user's own policy (``--method FILE.py:CLASS``) in the contention world's sweeps: its rows beside
the built-in methods, its identity in every point's, and the run's fail-fast on its first request."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest
from in_process import run_in_process

from yafs_safetail.commands import failure_sweep, load_sweep
from yafs_safetail.methods.registry import UserMethod
from yafs_safetail.runs.sweep_config import SWEEP_WORLD, SweepConfig
from yafs_safetail.runs.sweep_learners import training_requests
from yafs_safetail.runs.sweep_points import point_specs

REPOSITORY = Path(__file__).resolve().parents[1]
NEAREST_FREE = f"{REPOSITORY / 'examples' / 'custom_policy' / 'nearest_free.py'}:NearestFree"
BAD_POLICIES = REPOSITORY / "tests" / "bad_policies.py"
#: The smallest sweeps: ten users, 400 test requests per point, no SafeTail to train.
TINY = ("--users", "10", "--steps-scale", "0.02", "--no-safetail", "--workers", "1", "--seed", "2")


def test_the_load_sweep_runs_a_users_policy_beside_the_built_in_methods(tmp_path):
    args = (*TINY, "--loads", "0.2,0.8", "--methods", "Oracle,Rand-1", "--method", NEAREST_FREE,
            "--method", f"Mine={NEAREST_FREE}")
    done = run_in_process(load_sweep.main, *args, "--out", tmp_path / "a")
    assert done.returncode == 0, done.stderr
    frame = pd.read_csv(tmp_path / "a" / "sweep.csv")
    assert frame["method"].tolist() == ["Oracle", "Rand-1", "NearestFree", "Mine"] * 2
    # Named as in a run; the same policy under two names draws the same servers.
    rows = frame.set_index(["load", "method"])
    assert rows.loc[(0.8, "NearestFree"), "p99_s"] == rows.loc[(0.8, "Mine"), "p99_s"]
    assert "| load | Oracle | Rand-1 | NearestFree | Mine |" in (tmp_path / "a" / "SWEEP.md").read_text()
    # "The best fixed method" (in bold, and in the goals) is a built-in one, never a user's.
    p99_rows = [line.split(" | ") for line in done.stdout.split("Copies per request")[0].splitlines()
                if line.startswith("| 0.")]
    assert len(p99_rows) == 2 and all("**" not in "".join(cells[3:]) for cells in p99_rows), done.stdout
    run = json.loads((tmp_path / "a" / "run.json").read_text())
    assert run["user_methods"] == [NEAREST_FREE, f"Mine={NEAREST_FREE}"]
    settings = json.loads((tmp_path / "a" / "campaign.json").read_text())["runs"][0]["settings"]
    assert settings["user_methods"] == [NEAREST_FREE, f"Mine={NEAREST_FREE}"]
    # Its generator comes from the seed: the same command gives the same bytes.
    again = run_in_process(load_sweep.main, *args, "--out", tmp_path / "b")
    assert again.returncode == 0, again.stderr
    for name in ("sweep.csv", "SWEEP.md"):
        assert (tmp_path / "a" / name).read_text().replace(str(tmp_path / "a"), "") == \
            (tmp_path / "b" / name).read_text().replace(str(tmp_path / "b"), ""), name


def test_the_failure_sweep_runs_a_users_policy_beside_the_built_in_methods(tmp_path):
    learner = f"{REPOSITORY / 'tests' / 'counting_learner.py'}:CountingLearner"
    done = run_in_process(failure_sweep.main, *TINY, "--failure-levels", "0,0.2", "--failure-mttr-s", "5",
                          "--methods", "Rand-1,Rand-2", "--method", NEAREST_FREE, "--method", learner,
                          "--out", tmp_path / "f")
    assert done.returncode == 0, done.stderr
    frame = pd.read_csv(tmp_path / "f" / "failure_sweep.csv")
    assert frame["method"].tolist() == ["Rand-1", "Rand-2", "NearestFree", "CountingLearner"] * 2
    assert "| failure_level | Rand-1 | Rand-2 | NearestFree | CountingLearner |" in done.stdout
    assert json.loads((tmp_path / "f" / "run.json").read_text())["user_methods"] == [NEAREST_FREE, learner]
    # A policy that learns is trained first, on the paper SafeTail's budget, then tested.
    learned = frame[frame["method"] == "CountingLearner"]
    assert (learned["train_requests"] == training_requests("paper", 1, 0.02)).all()
    assert (learned["mean_n_selected"] == 1).all() and (frame[frame["method"] != "CountingLearner"][
        "train_requests"] == 0).all()
    assert "CountingLearner trained on" in (tmp_path / "f" / "level-0.2" / "run.log").read_text()


def test_a_points_identity_holds_the_users_policies_and_their_files(tmp_path):
    base = replace(SWEEP_WORLD, users=10)
    plain = SweepConfig(base=base, loads=(0.5,))
    assert "user_methods" not in point_specs(plain)[0].settings  # every earlier point keeps its id
    source = tmp_path / "mine.py"
    source.write_text((REPOSITORY / "examples" / "custom_policy" / "nearest_free.py").read_text())
    mine = SweepConfig(base=base, loads=(0.5,), user_methods=(UserMethod(f"{source}:NearestFree"),))
    renamed = replace(mine, user_methods=(UserMethod(f"Mine={source}:NearestFree"),))
    ids = {point_specs(config)[0].run_id for config in (plain, mine, renamed)}
    assert len(ids) == 3
    # The point is rebuilt from its settings alone (in whichever process runs it).
    spec = point_specs(mine)[0]
    assert [m.name for m in SweepConfig.from_point_settings(spec.settings).user_methods] == ["NearestFree"]
    source.write_text(source.read_text() + "\n# edited\n")  # an edited file is another point
    assert point_specs(mine)[0].run_id != spec.run_id


PROBE_SWEEPS = {"load": ("load_sweep.py", "--loads", "0.2,0.8"), "failure": ("failure_sweep.py",)}


@pytest.mark.parametrize("sweep", sorted(PROBE_SWEEPS))
def test_a_policy_that_cannot_choose_stops_the_sweep_before_anything_runs(tmp_path, sweep):
    from test_first_answer import PROBE

    script, *axis = PROBE_SWEEPS[sweep]
    done = subprocess.run([sys.executable, "-c", PROBE, str(REPOSITORY / "experiments" / script), *axis,
                           "--users", "10", "--steps-scale", "0.02", "--methods", "Oracle",
                           "--method", NEAREST_FREE, "--method", f"{BAD_POLICIES}:Empty", "--out", tmp_path / "s"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 2, done.stderr
    error, loaded = done.stderr.splitlines()
    assert error == (f"error: --method {BAD_POLICIES}:Empty: on the sweep's first request, Empty.choose() "
                     "returned []: no server: choose at least one of 0..4")
    # Before TensorFlow loads: no SafeTail built, no point computed, nothing written.
    assert "tensorflow" not in loaded and "keras" not in loaded, loaded
    assert list(tmp_path.iterdir()) == []


def test_a_policy_that_fails_mid_point_is_one_line_and_leaves_nothing(tmp_path):
    done = run_in_process(load_sweep.main, *TINY, "--loads", "0.5", "--methods", "Oracle",
                          "--method", f"{BAD_POLICIES}:RaisesLate", "--out", tmp_path / "s")
    assert done.returncode == 1
    line = [line for line in done.stderr.splitlines() if line.startswith("warning: ") and "failed load-0.5" in line]
    assert len(line) == 1 and "RaisesLate.choose() raised on request 30: RuntimeError: late bug (bad_policies.py " \
        "line" in line[0], done.stderr
    assert done.stderr.splitlines()[-1].startswith("error: 1 point(s) failed (see above); no tables written")
    assert not (tmp_path / "s").exists()


def test_a_users_policy_named_as_another_method_of_the_sweep_is_one_line(tmp_path):
    done = run_in_process(load_sweep.main, *TINY, "--loads", "0.5", "--methods", "Tied",
                          "--method", f"Tied={NEAREST_FREE}", "--out", tmp_path / "s")
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "the name 'Tied' is taken by another method of the sweep" in done.stderr
    assert not (tmp_path / "s").exists()



def test_a_policy_file_in_the_methods_list_runs_as_with_method(tmp_path):
    # The command a user first tries (issue 50): a file beside the built-in names in --methods.
    done = run_in_process(load_sweep.main, *TINY, "--loads", "0.2,0.8", "--methods", f"Oracle,{NEAREST_FREE}",
                          "--out", tmp_path / "listed")
    assert done.returncode == 0, done.stderr
    listed = pd.read_csv(tmp_path / "listed" / "sweep.csv")
    assert listed["method"].tolist() == ["Oracle", "NearestFree"] * 2
    given = run_in_process(load_sweep.main, *TINY, "--loads", "0.2,0.8", "--methods", "Oracle",
                           "--method", NEAREST_FREE, "--out", tmp_path / "given")
    assert given.returncode == 0, given.stderr
    pd.testing.assert_frame_equal(listed, pd.read_csv(tmp_path / "given" / "sweep.csv"))
