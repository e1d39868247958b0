"""experiments/run_usecase.py as users run it: tiny budgets, its folder and errors.

Bad input fails before TensorFlow is imported and must end in exactly one ``error:`` line on
stderr, exit code 2, no traceback, and no change to an earlier results folder at ``--out``; it
and the first run (an empty stderr) run in a subprocess. Checks of other successful runs'
files run the command in this process (``tests/in_process.py``), which imports TensorFlow only once.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from in_process import run_usecase_here as run_here

from yafs_safetail import results
from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS
from yafs_safetail.edge.calibration import world_settings
from yafs_safetail.results.figures.run_figures import (
    FIGURE_STEMS,
    FIGURES_DIR,
    build_figures,
    read_figure_inputs,
)
from yafs_safetail.runs.experiment import POLICY_FILE, REPOSITORY, YAFS_DIR, baseline_names

SCRIPT = REPOSITORY / "experiments" / "run_usecase.py"
EXAMPLE = REPOSITORY / "examples" / "custom_policy" / "nearest_free.py"
BAD_POLICIES = Path(__file__).resolve().parent / "bad_policies.py"
TINY = ["--steps-scale", "0.02", "--redundancy", "1,2"]
FIGURES = [f"{stem}.{ext}" for stem in FIGURE_STEMS.values() for ext in DEFAULT_FIGURE_FORMATS]


def run_script(*args: str | Path, cwd: Path = REPOSITORY) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "YAFS_SAFETAIL_DEBUG"}
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def earlier_results(folder: Path) -> dict[str, bytes]:
    """Make ``folder`` look like an earlier run's results; returns what must survive."""
    folder.mkdir(parents=True)
    (folder / "requests.csv").write_text("method,phase\nSafeTail,test\n")
    (folder / "run.json").write_text('{"package_version": "0.1.0"}\n')
    (folder / "summary.md").write_text("# an earlier run\n")
    return snapshot(folder)


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def assert_one_error_line(done: subprocess.CompletedProcess[str], *fragments: str) -> str:
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("error: ")
    for fragment in fragments:
        assert fragment in lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def uc1_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("uc1") / "run"
    done = run_script("--uc", "1", "--seed", "4", "--out", out, "--quiet", "--yafs-csv", *TINY)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""  # --quiet: no progress, and TensorFlow's start-up notes are silenced
    assert done.stdout == f"{out}\n"  # --quiet: only the folder's path; the table is in summary.md
    assert "| SafeTail |" in (out / "summary.md").read_text()
    return out


def test_uc1_writes_the_whole_folder(uc1_run):
    out = uc1_run
    methods = [results.SAFETAIL, *baseline_names((1, 2))]
    requests = results.read_requests_csv(out / "requests.csv")
    assert list(requests.columns[: len(results.REQUESTS_COLUMNS)]) == list(results.REQUESTS_COLUMNS)
    assert set(requests["method"]) == set(methods)
    assert len(requests[requests["phase"] == "train"]) == 200
    assert (requests[requests["phase"] == "test"].groupby("method").size() == 80).all()

    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["method"]) == methods
    assert list(summary.columns) == list(results.SUMMARY_COLUMNS)
    assert (summary["n_requests"] == 80).all()
    markdown = (out / "summary.md").read_text()
    assert "use case 1" in markdown and "Oracle over SafeTail" in markdown

    run = json.loads((out / "run.json").read_text())
    assert run["preset"] == "paper" and run["seed"] == 4 and run["use_case"] == 1
    assert run["methods"] == methods and run["train_steps"] == 200 and run["test_steps"] == 80
    assert run["topology"] == "topologies/paper_5servers.json"
    assert "--uc 1" in run["command"]

    assert (out / POLICY_FILE).stat().st_size > 0
    yafs = {p.name for p in (out / YAFS_DIR).iterdir()}
    for method, phase in [(results.SAFETAIL, "train"), *((m, "test") for m in methods)]:
        assert {f"{method}_{phase}.csv", f"{method}_{phase}_link.csv"} <= yafs
    module_rows = pd.read_csv(out / YAFS_DIR / "Oracle_test.csv")
    assert {"id", "type", "time_in", "time_out"} <= set(module_rows.columns)
    assert len(module_rows) > 0

    figures = sorted(p.name for p in (out / FIGURES_DIR).iterdir())
    assert figures == sorted(FIGURES)
    assert all((out / FIGURES_DIR / name).stat().st_size > 0 for name in figures)
    # Nothing temporary is left beside the published folder.
    assert [p.name for p in out.parent.iterdir()] == ["run"]


def test_saved_policy_is_evaluated_without_training(uc1_run, tmp_path):
    out = tmp_path / "eval"
    done = run_here("--uc", "1", "--seed", "4", "--policy", uc1_run / POLICY_FILE, "--out", out,
                      "--quiet", "--no-figures", "--no-yafs-csv", *TINY)
    assert done.returncode == 0, done.stderr
    requests = results.read_requests_csv(out / "requests.csv")
    assert set(requests["phase"]) == {"test"}
    run = json.loads((out / "run.json").read_text())
    assert run["train_steps"] == 0 and run["n_servers"] == 5
    assert run["policy_source"] == str(uc1_run / POLICY_FILE)
    # The same test world and a greedy policy: the trained run's test rows are reproduced.
    trained = results.read_requests_csv(uc1_run / "requests.csv")
    trained = trained[(trained["phase"] == "test") & (trained["method"] == results.SAFETAIL)]
    evaluated = requests[requests["method"] == results.SAFETAIL]
    assert list(evaluated["servers"]) == list(trained["servers"])
    assert list(evaluated["latency_s"]) == list(trained["latency_s"])
    assert not (out / FIGURES_DIR).exists() and not (out / YAFS_DIR).exists()


def test_users_methods_join_the_comparison_on_the_same_requests(uc1_run, tmp_path):
    out = tmp_path / "mine"
    done = run_here("--uc", "1", "--seed", "4", "--policy", uc1_run / POLICY_FILE, "--out", out,
                      "--quiet", "--no-yafs-csv", "--method", f"{EXAMPLE}:NearestFree",
                      "--method", f"Nearest again={EXAMPLE}:NearestFree", *TINY)
    assert done.returncode == 0, done.stderr
    mine = ["NearestFree", "Nearest again"]
    requests = results.read_requests_csv(out / "requests.csv")
    rows = {name: requests[requests["method"] == name] for name in mine}
    assert all(len(part) == 80 for part in rows.values())
    # Same requests and random numbers: the same deterministic policy gives the same rows, and
    # the built-in methods' rows are those of the run without the user's methods.
    columns = ["step", "servers", "latency_s", "refused", "fallback"]
    assert rows["NearestFree"][columns].values.tolist() == rows["Nearest again"][columns].values.tolist()
    # One copy, or two when the nearest server with room is busy; choices of its own, neither
    # MinProp-1's (the nearest server) nor MinProp-2's (the two nearest).
    assert set(rows["NearestFree"]["n_selected"]) <= {1, 2}
    for baseline in ("MinProp-1", "MinProp-2"):
        assert list(rows["NearestFree"]["servers"]) != list(requests[requests["method"] == baseline]["servers"])
    earlier = results.read_requests_csv(uc1_run / "requests.csv")
    oracle = [part[part["method"] == "Oracle"]["latency_s"].tolist() for part in (requests, earlier)]
    assert oracle[0] == oracle[1]
    assert (rows["NearestFree"]["latency_s"].to_numpy() >= requests[requests["method"] == "Oracle"]["latency_s"].to_numpy()).all()

    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["method"])[-2:] == sorted(mine)
    assert json.loads((out / "run.json").read_text())["methods"][-2:] == sorted(mine)
    assert all(f"| {name} |" in (out / "summary.md").read_text() for name in mine)
    frame, run = read_figure_inputs(out)
    panel_a = build_figures(frame, run)["a"]
    legend = panel_a.axes[0].get_legend_handles_labels()[1]
    assert set(mine) <= set(legend)


def test_policy_for_another_number_of_servers_is_refused(uc1_run, tmp_path):
    out = tmp_path / "eval"
    kept = earlier_results(out)
    done = run_script("--overwrite", "--uc", "1", "--policy", uc1_run / POLICY_FILE, "--out", out,
                      "--topology", REPOSITORY / "topologies" / "3servers.json", *TINY)
    # Checked from the policy's sidecar before TensorFlow loads: exactly one line.
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: ")
    assert "5 servers" in done.stderr and "3 servers" in done.stderr
    assert snapshot(out) == kept


@pytest.mark.parametrize("uc", [2, 3])
def test_other_use_cases_run(tmp_path, uc):
    out = tmp_path / f"uc{uc}"
    done = run_here("--uc", uc, "--out", out, "--quiet", "--no-figures",  # YAFS CSVs: off by default
                      "--steps-scale", "0.025", "--redundancy", "1", "--workers", uc - 1)
    assert done.returncode == 0, done.stderr
    run = json.loads((out / "run.json").read_text())
    assert run["use_case"] == uc and run["preset"] == "paper"
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["method"]) == [results.SAFETAIL, *baseline_names((1,))]
    assert (summary["p50_s"] > 0).all()
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["requests.csv", "run.json", "run.log", "summary.csv", "summary.md", POLICY_FILE, f"{POLICY_FILE}.json"]
    )


@pytest.mark.slow
@pytest.mark.parametrize("uc", [1, 2, 3])
def test_tuned_preset_with_figures_and_yafs_csvs(tmp_path, uc):
    out = tmp_path / f"uc{uc}"
    done = run_script("--uc", uc, "--preset", "tuned", "--seed", "1", "--out", out, "--quiet",
                      "--steps-scale", "0.1", "--yafs-csv", "--figure-format", "pdf,png")
    assert done.returncode == 0, done.stderr
    assert json.loads((out / "run.json").read_text())["preset"] == "tuned"
    assert sorted(p.name for p in (out / FIGURES_DIR).iterdir()) == sorted(
        f"{stem}.{ext}" for stem in FIGURE_STEMS.values() for ext in ("png", "pdf"))


def test_help():
    done = run_script("--help")
    assert done.returncode == 0 and done.stderr == ""
    for option in ("--uc", "--preset", "--seed", "--out", "--steps-scale", "--policy", "--topology"):
        assert option in done.stdout


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--uc", "4"], ["--uc", "4"]),
        (["--uc", "one"], ["--uc", "one"]),
        ([], ["--uc"]),
        (["--uc", "1", "--preset", "fancy"], ["--preset", "fancy"]),
        (["--uc", "1", "--seed", "-1"], ["--seed", "-1"]),
        (["--uc", "1", "--seed", "abc"], ["--seed", "abc"]),
        (["--uc", "1", "--steps-scale", "0"], ["--steps-scale"]),
        (["--uc", "1", "--redundancy", "1,9"], ["--redundancy", "x=9"]),
        (["--uc", "1", "--workers", "0"], ["--workers", "0"]),
        (["--uc", "1", "--bogus"], ["--bogus"]),
        (["--uc", "1", "--method", "nowhere.py:Mine"], ["--method", "nowhere.py", "no such file"]),
        (["--uc", "1", "--method", f"{EXAMPLE}:Nope"], ["--method", "Nope", "not a Policy subclass"]),
        (["--uc", "1", "--method", f"A={EXAMPLE}:NearestFree", "--method", f"A={EXAMPLE}:NearestFree"],
         ["--method", "two methods are named 'A'"]),
        # At the full budget: found on the first request, long before SafeTail's training ends.
        (["--uc", "1", "--method", f"{BAD_POLICIES}:Empty"],
         [f"--method {BAD_POLICIES}:Empty", "Empty.choose() returned []", "no server"]),
        (["--uc", "2", "--method", f"{BAD_POLICIES}:Raises"],
         [f"--method {BAD_POLICIES}:Raises", "raised IndexError", "bad_policies.py line"]),
    ],
)
def test_bad_arguments_give_one_line_and_keep_earlier_results(tmp_path, args, fragments):
    out = tmp_path / "earlier"
    kept = earlier_results(out)
    done = run_script("--overwrite", *args, "--out", out)
    assert_one_error_line(done, *fragments)
    assert snapshot(out) == kept
    assert [p.name for p in tmp_path.iterdir()] == ["earlier"]


def test_a_policy_that_fails_late_is_named_with_its_request_and_line(tmp_path):
    out = tmp_path / "earlier"
    kept = earlier_results(out)
    done = run_script("--overwrite", "--quiet", "--uc", "1", *TINY, "--no-figures", "--method",
                      f"{BAD_POLICIES}:RaisesLate", "--out", out)
    line = (BAD_POLICIES.read_text().splitlines().index('            raise RuntimeError("late bug")') + 1)
    assert_one_error_line(done, f"RaisesLate ({BAD_POLICIES}:RaisesLate)", "RaisesLate.choose() raised",
                          "request 30 of its phase", f"RuntimeError: late bug (bad_policies.py line {line})")
    assert snapshot(out) == kept  # nothing half-written in its place
    assert [p.name for p in tmp_path.iterdir()] == ["earlier"]


def test_a_policy_that_cannot_choose_stops_the_run_before_tensorflow_loads(tmp_path):
    from test_first_answer import PROBE

    done = subprocess.run([sys.executable, "-c", PROBE, str(SCRIPT), "--uc", "1", "--out", tmp_path / "run",
                           "--method", f"{BAD_POLICIES}:Twice"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 2, done.stderr
    error, loaded = done.stderr.splitlines()
    assert error.startswith(f"error: --method {BAD_POLICIES}:Twice: ") and "server 1 is chosen twice" in error
    assert "tensorflow" not in loaded and "keras" not in loaded, loaded
    assert list(tmp_path.iterdir()) == []  # no results, no checkpoint, not even results/


def test_topology_that_is_not_json(tmp_path):
    topology = tmp_path / "broken.json"
    topology.write_text("{ not json")
    out = tmp_path / "earlier"
    kept = earlier_results(out)
    done = run_script("--overwrite", "--uc", "1", "--topology", topology,
                      "--placement", REPOSITORY / "placements" / "paper_5servers.json", "--out", out)
    assert_one_error_line(done, "broken.json")
    assert snapshot(out) == kept


def test_topology_with_an_unknown_condition(tmp_path):
    data = json.loads((REPOSITORY / "topologies" / "paper_5servers.json").read_text())
    for link in data["link"]:
        if "condition" in link:
            link["condition"] = 9
            break
    topology = tmp_path / "far.json"
    topology.write_text(json.dumps(data))
    out = tmp_path / "earlier"
    kept = earlier_results(out)
    done = run_script("--overwrite", "--uc", "1", "--topology", topology,
                      "--placement", REPOSITORY / "placements" / "paper_5servers.json", "--out", out)
    assert_one_error_line(done, "far.json", "condition", "9")
    assert snapshot(out) == kept


def test_missing_topology_and_default_placement(tmp_path):
    done = run_script("--uc", "1", "--topology", tmp_path / "nowhere.json", "--out", tmp_path / "run")
    assert_one_error_line(done, f"{tmp_path / 'nowhere.json'}: file: topology file not found")
    assert not (tmp_path / "run").exists()


def test_a_topology_without_a_placement_asks_for_one(tmp_path):
    topology = tmp_path / "mine.json"
    topology.write_bytes((REPOSITORY / "topologies" / "3servers.json").read_bytes())
    done = run_script("--uc", "1", "--topology", topology, "--out", tmp_path / "run")
    assert_one_error_line(done, str(REPOSITORY / "placements" / "mine.json"), "placement file not found",
                          f"--topology {topology}", "pass --placement")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.json"]


def test_output_whose_parent_is_a_file(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    done = run_script("--uc", "1", "--out", blocker / "run", *TINY)
    assert_one_error_line(done, "--out", str(blocker))
    assert blocker.read_text() == "not a folder"


def test_output_that_is_a_file(tmp_path):
    target = tmp_path / "results"
    target.write_text("keep me")
    done = run_script("--uc", "1", "--out", target, *TINY)
    assert_one_error_line(done, "--out", "not a folder")
    assert target.read_text() == "keep me"


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc")
def test_output_in_a_folder_nobody_can_write(tmp_path):
    # /proc refuses new entries even to root (the read-only folder test below needs non-root).
    done = run_script("--uc", "1", "--out", "/proc/yafs_safetail_run", *TINY)
    assert_one_error_line(done, "--out", "/proc")


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes anywhere")
def test_output_under_a_read_only_folder(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    kept = earlier_results(locked / "run")
    locked.chmod(0o555)
    try:
        done = run_script("--overwrite", "--uc", "1", "--out", locked / "run", *TINY)
    finally:
        locked.chmod(0o755)
    assert_one_error_line(done, "--out", "not writable")
    assert snapshot(locked / "run") == kept


def test_target_latency_and_load_level_options(tmp_path, uc1_default_run):
    out = tmp_path / "fixed"
    done = run_here("--uc", "1", "--out", out, "--quiet", "--no-figures", *TINY,
                      "--target-latency-s", "0.75", "--load-peak-users", "0")
    assert done.returncode == 0, done.stderr
    rows = pd.read_csv(out / "requests.csv")
    assert (rows["target_s"] == 0.75).all()
    # Idle servers: one request's copies never fill a server, so nothing is ever refused.
    assert not rows["refused"].any() and not rows["fallback"].any()
    run = json.loads((out / "run.json").read_text())
    world = run["world"]
    assert world["target_latency_s"] == 0.75 and world["load_peak_users"] == 0
    # Both options changed the preset's world: recorded, and summary.md scores no closeness.
    assert run["world_overrides"] == {"target_latency_s": 0.75, "load_peak_users": 0.0}
    assert "**Closeness to the paper: not scored.**" in (out / "summary.md").read_text()
    # The default: Eq. 4 per request (targets vary) and the preset world's load.
    default_out = uc1_default_run
    default_run = json.loads((default_out / "run.json").read_text())
    assert "world_overrides" not in default_run
    assert default_run["placement"] == "placements/paper_5servers.json"
    text = (default_out / "summary.md").read_text()
    assert "**Closeness to the paper (this run):" in text
    assert "**Too few test requests for " in text  # the tiny budget's few test requests
    default = pd.read_csv(default_out / "requests.csv")
    assert default["target_s"].nunique() > 1
    # The calibrated world's load (no server is ever full there, so nothing to count refusals by).
    assert default_run["world"]["load_peak_users"] == world_settings("calibrated").load_peak_users > 0


def test_target_compute_option_is_recorded_and_changes_only_the_target(tmp_path):
    runs = {}
    for reading in ("request", "trace_median"):
        out = tmp_path / reading
        done = run_here("--uc", "3", "--out", out, "--quiet", "--no-figures", *TINY, "--workers", "1",
                          "--target-compute", reading)
        assert done.returncode == 0, done.stderr
        run = json.loads((out / "run.json").read_text())
        assert run["world"]["target_compute"] == reading
        # Only an option that changes the preset's world is an override (and unscored).
        own = world_settings("calibrated").target_compute
        assert run.get("world_overrides") == (None if reading == own else {"target_compute": reading})
        runs[reading] = pd.read_csv(out / "requests.csv")
    request, trace = runs["request"], runs["trace_median"]
    # UC3's compute depends on the clip: the target follows the request's input or not.
    assert not np.allclose(request["target_s"], trace["target_s"])
    baselines = request["method"] != "SafeTail"
    pd.testing.assert_frame_equal(request.loc[baselines, ["method", "request_id", "latency_s"]],
                                  trace.loc[baselines, ["method", "request_id", "latency_s"]])


@pytest.fixture(scope="module")
def uc1_default_run(tmp_path_factory) -> Path:
    """UC1 with every option at its default (the tests of options compare with it)."""
    out = tmp_path_factory.mktemp("default") / "run"
    done = run_here("--uc", "1", "--out", out, "--quiet", "--no-figures", *TINY)
    assert done.returncode == 0, done.stderr
    return out


def test_learning_rate_option_trains_safetail_at_that_rate_and_says_so(tmp_path, uc1_default_run):
    out = tmp_path / "faster"
    done = run_here("--uc", "1", "--out", out, "--quiet", "--no-figures", *TINY,
                      "--learning-rate", "0.003")
    assert done.returncode == 0, done.stderr
    run = json.loads((out / "run.json").read_text())
    assert run["learning_rate_override"] == 0.003 and run["learner"]["learning_rate"] == 0.003
    assert run["preset"] == "paper"
    title = (out / "summary.md").read_text().splitlines()[0]
    assert "preset `paper`, learning rate 0.003 (--learning-rate), seed 0" in title
    default = uc1_default_run
    preset_run = json.loads((default / "run.json").read_text())
    assert "learning_rate_override" not in preset_run
    assert preset_run["learner"]["learning_rate"] != 0.003
    assert "learning rate" not in (default / "summary.md").read_text().splitlines()[0]
    # Only SafeTail's training changes: the baselines meet the same requests with the same replies.
    faster, preset = pd.read_csv(out / "requests.csv"), pd.read_csv(default / "requests.csv")
    baselines = faster["method"] != "SafeTail"
    pd.testing.assert_frame_equal(faster[baselines].reset_index(drop=True),
                                  preset[preset["method"] != "SafeTail"].reset_index(drop=True))
    assert (out / POLICY_FILE).read_bytes() != (default / POLICY_FILE).read_bytes()


def test_learning_rate_with_a_saved_policy_is_refused(uc1_run, tmp_path):
    done = run_script("--uc", "1", "--policy", uc1_run / POLICY_FILE, "--learning-rate", "0.001",
                      "--out", tmp_path / "run")
    assert_one_error_line(done, "--learning-rate", "--policy")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("args, fragment", [
    (["--learning-rate", "0"], "--learning-rate"),
    (["--learning-rate", "nan"], "--learning-rate"),
    (["--learning-rate", "fast"], "--learning-rate"),
    (["--target-latency-s", "0"], "--target-latency-s"),
    (["--target-latency-s", "nan"], "--target-latency-s"),
    (["--load-peak-users", "-1"], "--load-peak-users"),
    (["--target-compute", "mean"], "--target-compute"),
])
def test_bad_target_or_load_is_one_line(tmp_path, args, fragment):
    done = run_script("--uc", "1", "--out", tmp_path / "run", *TINY, *args)
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1, done.stderr
    assert fragment in done.stderr and not (tmp_path / "run").exists()


def test_an_out_of_range_setting_in_a_config_is_one_line(tmp_path):
    from yafs_safetail.runs.experiment import ExperimentConfig, ExperimentError, run_experiment

    with pytest.raises(ExperimentError, match="--target-latency-s"):
        run_experiment(ExperimentConfig(out_dir=tmp_path / "run", target_latency_s=float("inf")))
    for rate in (float("inf"), -1e-3, True):
        with pytest.raises(ExperimentError, match="--learning-rate"):
            run_experiment(ExperimentConfig(out_dir=tmp_path / "run", learning_rate=rate))  # type: ignore[arg-type]
    assert not (tmp_path / "run").exists()
