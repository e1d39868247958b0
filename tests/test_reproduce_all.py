"""reproduce_all.py end to end on a tiny budget: run folders, REPORT.md, speedups.csv, bad input."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from in_process import Done, run_in_process

from yafs_safetail.logs import RUN_LOG_FILE

REPOSITORY = Path(__file__).resolve().parents[1]
SCRIPT = REPOSITORY / "experiments" / "reproduce_all.py"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          cwd=REPOSITORY, timeout=900)


def _run_here(*args: str) -> Done:
    """The command in this process, for checks of what a successful one writes
    (tests/in_process.py: TensorFlow imported once)."""
    from yafs_safetail.commands import reproduce_all

    return run_in_process(reproduce_all.main, *args)


TINY_ARGS = ("--uc", "1", "--seeds", "0,1", "--steps-scale", "0.013", "--no-figures")


@pytest.fixture(scope="module")
def uncut(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two seeds of use case 1, run without interruption."""
    out = tmp_path_factory.mktemp("reproduce") / "rep"
    done = _run_here(*TINY_ARGS, "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    return out


def _files(out: Path) -> dict[str, bytes]:
    """Every run folder's files (but run.log, whose times differ from run to run) and the
    reports, with the --out path taken out of the recorded command lines (the only place it
    appears)."""
    names = [p for p in sorted(out.rglob("*")) if p.is_file() and p.name != RUN_LOG_FILE
             and (p.parent != out or p.name in ("REPORT.md", "fidelity.csv", "feasibility.csv", "speedups.csv"))]
    return {str(p.relative_to(out)): p.read_bytes().replace(str(out).encode(), b"OUT") for p in names}


def test_two_seeds_one_use_case_make_a_report(uncut: Path) -> None:
    out = uncut
    for seed in (0, 1):
        assert (out / "uc1-paper" / f"seed{seed}" / "summary.csv").is_file()
    report = (out / "REPORT.md").read_text()
    assert "## Use case 1" in report and "preset `paper`" in report
    assert "as the code behind the paper's numbers chose" in report  # the baselines' reading (D16)
    assert "Oracle over SafeTail" in report and "SafeTail over Rand-1" in report
    assert "| 0 |" in report and "| 1 |" in report  # one diagnostics row per seed
    assert "### Why our ratios may differ" in report
    assert "not scored" not in report  # the paper's setting
    assert "Your methods" not in report and not (out / "methods.csv").exists()  # none given
    # The scorecard: every use-case-1 number of the paper, calibration and held-out apart.
    assert "## Fidelity scorecard — preset `paper`" in report
    assert "the scorecard is meant for five or more" in report
    card = pd.read_csv(out / "fidelity.csv")
    ratios = card[card["kind"] == "ratio"]
    assert len(ratios) == 16 and set(ratios["use_case"]) == {1}
    assert (ratios["subset"] == "calibration").sum() == 16  # all of use case 1's (docs/calibration.md)
    assert ratios["ours"].gt(0).all() and ratios["n_seeds"].eq(2).all()
    assert (card["kind"] == "claim").sum() == 3
    assert (out / "fidelity-paper.png").is_file()
    assert not (out / "fidelity-paper.pdf").exists()  # PDF copies only with --figure-format
    # What any policy could reach: four percentiles per seed, from the runs' Oracle and baselines.
    assert "## What any policy could reach in this world — preset `paper`" in report
    assert "Whatever the policy, in these worlds: at most" in report
    checked = pd.read_csv(out / "feasibility.csv")
    assert len(checked) == 8 and set(checked["seed"]) == {0, 1} and set(checked["preset"]) == {"paper"}
    assert (checked["floor_s"] > 0).all() and (checked["low_s"] >= checked["floor_s"]).all()
    assert not (checked["feasible"] & (checked["low_s"] > checked["high_s"])).any()
    assert (checked["feasible"] | (checked["low_s"] >= checked["high_s"])).all()
    speedups = pd.read_csv(out / "speedups.csv")
    assert set(speedups["preset"]) == {"paper"}
    stated = speedups[speedups["paper"].notna()]
    assert len(stated) > 0 and stated["n_seeds"].eq(2).all()


NEAREST_FREE = "examples/custom_policy/nearest_free.py:NearestFree"


def _row(report: str, title: str, method: str) -> list[str]:
    """The cells of ``method``'s row in REPORT.md's table under ``### title``."""
    section = report[report.index(f"### {title}\n"):]
    section = section[:section.index("LaTeX: ")]
    rows = [line.strip("| ").split(" | ") for line in section.splitlines() if line.startswith(f"| {method} |")]
    assert len(rows) == 1, section
    return rows[0]


def test_a_users_policy_in_every_seed_with_intervals_and_ratios(tmp_path: Path) -> None:
    from test_results_latex import interval_cell

    from yafs_safetail import results

    out = tmp_path / "rep"
    seeds = (0, 1, 2)  # fewer than the scorecard's five: a note, not an error
    done = _run_here("--uc", "1", "--seeds", ",".join(map(str, seeds)), "--steps-scale", "0.013",
                     "--no-figures", "--method", NEAREST_FREE, "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    report = (out / "REPORT.md").read_text()
    assert "Only 3 seed(s): the scorecard is meant for five or more." in report
    summaries = [results.read_summary_csv(out / "uc1-paper" / f"seed{seed}") for seed in seeds]
    mine = [s[s["method"] == "NearestFree"].iloc[0] for s in summaries]
    # The section's own latency table holds the policy too, and a table of its own beside
    # SafeTail and Oracle gives each percentile and its servers per request over the seeds.
    assert _row(report, "Latency (test phase)", "NearestFree")[1] == "3"
    for method in ("SafeTail", "Oracle"):
        assert _row(report, "Your methods beside SafeTail and Oracle", method)[1] == "3"
    row = _row(report, "Your methods beside SafeTail and Oracle", "NearestFree")
    for column, metric in enumerate(("p50_s", "p90_s", "p95_s", "p99_s", "mean_n_selected"), start=2):
        digits = 2 if metric == "mean_n_selected" else 3
        expected = interval_cell(*results.bootstrap_interval([m[metric] for m in mine]), digits)
        assert row[column] == expected, (metric, row)
        assert "[" in row[column] or len({m[metric] for m in mine}) == 1  # an interval over seeds
    # Its speed-ups over SafeTail and Oracle: per seed, then the geometric mean and t-interval.
    for reference in ("SafeTail", "Oracle"):
        row = _row(report, "Your methods' speed-ups over SafeTail and Oracle", f"NearestFree | {reference}")
        theirs = [s[s["method"] == reference].iloc[0] for s in summaries]
        for column, percentile in enumerate((50, 90, 95, 99), start=3):
            ratios = [t[f"p{percentile}_s"] / m[f"p{percentile}_s"] for t, m in zip(theirs, mine, strict=True)]
            assert row[column] == interval_cell(*results.geometric_interval(ratios), 2)
    # The same numbers for scripts, and both tables as LaTeX.
    numbers = pd.read_csv(out / "methods.csv")
    assert set(numbers["method"]) == {"NearestFree"} and numbers["n_seeds"].eq(3).all()
    p99 = numbers[numbers["metric"] == "p99_s"].iloc[0]
    assert p99["mean"] == pytest.approx(sum(m["p99_s"] for m in mine) / 3)
    assert p99["ci_low"] <= p99["mean"] <= p99["ci_high"]
    assert {"speedup_over_SafeTail_p99", "speedup_over_Oracle_p50"} <= set(numbers["metric"])
    for name in ("methods-uc1-paper", "methods-ratios-uc1-paper"):
        assert (out / "tables" / f"{name}.tex").is_file() and f"tables/{name}.tex" in report


def test_unknown_use_case_and_preset_and_repeated_seeds_are_one_line_errors(tmp_path: Path) -> None:
    for args in (("--uc", "4"), ("--preset", "fast"), ("--seeds", "0,1,0"), ("--target-compute", "mean"),
                 ("--learning-rate", "0"), ("--method", "nowhere.py:Policy"),
                 ("--method", NEAREST_FREE, "--method", NEAREST_FREE)):
        done = _run(*args, "--out", str(tmp_path / "x"))
        assert done.returncode == 2
        assert done.stderr.startswith("error:") and done.stderr.count("\n") == 1
        assert "Traceback" not in done.stderr


def test_target_compute_and_learning_rate_reach_every_run(tmp_path: Path) -> None:
    out = tmp_path / "rep"
    done = _run_here("--uc", "3", "--seeds", "0", "--steps-scale", "0.013", "--no-figures",
                     "--target-compute", "trace_median", "--learning-rate", "0.001", "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    run = json.loads((out / "uc3-paper" / "seed0" / "run.json").read_text())
    assert run["world"]["name"] == "calibrated" and run["world"]["target_compute"] == "trace_median"
    assert run["learner"]["learning_rate"] == 0.001 and run["learning_rate_override"] == 0.001
    # The report says its runs are not the preset's own.
    report = (out / "REPORT.md").read_text()
    assert "learning rate 0.001 (`--learning-rate`) instead of its preset's" in report
    # --target-compute changed the preset's world: the report does not score closeness.
    assert "**Closeness to the paper: not scored.**" in report and "--target-compute" in report


@pytest.mark.slow  # a whole reproduction killed and resumed; the others run the entry point
def test_a_killed_reproduction_resumes_to_the_same_files_without_recomputing(uncut: Path, tmp_path: Path) -> None:
    out = tmp_path / "rep"
    args = [sys.executable, str(SCRIPT), *TINY_ARGS, "--workers", "1", "--out", str(out)]
    process = subprocess.Popen(args, cwd=REPOSITORY, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = out / "uc1-paper" / "seed0" / "run.json"
    deadline = time.monotonic() + 300
    while not first.is_file() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)  # half way: seed 0 done, seed 1 under way or queued
    process.wait()
    assert first.is_file() and not (out / "REPORT.md").exists()
    stamp = first.stat()
    done = _run(*TINY_ARGS, "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    assert "1 computed now, 1 done earlier (not recomputed), 0 failed" in done.stderr
    assert (first.stat().st_ino, first.stat().st_mtime_ns) == (stamp.st_ino, stamp.st_mtime_ns)
    resumed, reference = _files(out), _files(uncut)
    assert resumed.keys() == reference.keys()
    for name in reference:
        assert resumed[name] == reference[name], f"{name} differs from the uninterrupted run"


def test_latex_tables_and_band_figures_beside_the_report(uncut: Path) -> None:
    from test_results_latex import interval_cell, parse_table

    from yafs_safetail import results

    out = uncut
    report = (out / "REPORT.md").read_text()
    names = ["fidelity-paper-ratios", "fidelity-paper-claims", "fidelity-paper-access-rate",
             "feasibility-paper", "latency-uc1-paper", "ratios-uc1-paper", "learner-uc1-paper"]
    assert sorted(p.name for p in (out / "tables").iterdir()) == sorted(f"{n}.tex" for n in names)
    listed = report[report.index("## LaTeX tables"):]
    assert [line for line in listed.splitlines() if line.startswith("- ")] == [
        f"- [`tables/{n}.tex`](tables/{n}.tex)" for n in names]
    # The latency table holds REPORT.md's numbers: the mean over both seeds and its interval.
    folders = [out / "uc1-paper" / f"seed{seed}" for seed in (0, 1)]
    stats = results.aggregate_summaries(folders)
    header, rows = parse_table((out / "tables" / "latency-uc1-paper.tex").read_text())
    assert header[2] == "median (s)"
    assert [row[0] for row in rows] == results.sort_methods(stats["method"].unique())
    safetail = stats[stats["method"] == "SafeTail"].set_index("metric").loc["p99_s"]
    assert rows[0][5] == interval_cell(safetail["mean"], safetail["ci_low"], safetail["ci_high"], 3)
    assert rows[0][5] in report
    _, claims = parse_table((out / "tables" / "fidelity-paper-claims.tex").read_text())
    assert len(claims) == 3
    header, rows = parse_table((out / "tables" / "feasibility-paper.tex").read_text())
    assert header[:4] == ["use case", "percentile", "statements", "reachable in seeds"]
    assert [row[1] for row in rows] == ["median", "p90", "p95", "p99"]
    # Band figures across seeds, even with --no-figures (that skips the per-run panels only).
    for stem in ("uc1-paper-latency-bands", "uc1-paper-servers-bands"):
        assert (out / "figures" / f"{stem}.png").stat().st_size > 0
        assert not (out / "figures" / f"{stem}.pdf").exists()
        assert f"(figures/{stem}.png)" in report
    assert not (out / "uc1-paper" / "seed0" / "figures").exists()


def test_a_run_without_its_fallback_latency_is_one_line_naming_the_file(uncut: Path, tmp_path: Path) -> None:
    import json
    import shutil

    from yafs_safetail.results import feasibility

    world = feasibility.read_world_run(uncut / "uc1-paper" / "seed0")
    assert world.use_case == 1 and world.seed == 0 and world.floor_s[50] <= world.floor_s[99]
    broken = tmp_path / "seed0"
    shutil.copytree(uncut / "uc1-paper" / "seed0", broken)
    run = json.loads((broken / "run.json").read_text())
    del run["fallback_latency_s"]
    (broken / "run.json").write_text(json.dumps(run))
    with pytest.raises(ValueError, match=r"seed0/run.json: key fallback_latency_s: expected a number"):
        feasibility.read_world_run(broken)


def test_the_check_on_any_run_folders_from_the_command_line(uncut: Path, tmp_path: Path) -> None:
    command = [sys.executable, "-m", "yafs_safetail.commands.feasibility"]
    folders = [str(uncut / "uc1-paper" / f"seed{seed}") for seed in (0, 1)]
    done = subprocess.run([*command, *folders], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("Whatever the policy, in these worlds: at most ")
    assert "| 1 | p99 | " in done.stdout and "of 2 |" in done.stdout
    missing = subprocess.run([*command, str(tmp_path / "nowhere")], capture_output=True, text=True,
                             timeout=300)
    assert missing.returncode == 2 and missing.stdout == ""
    assert missing.stderr.strip().splitlines() == [f"error: {tmp_path / 'nowhere'}: results folder not found"]
