"""Runs never lose data: protected and foreign folders are refused, earlier runs are replaced
only with --overwrite, a second run on the same folder fails at once, and SIGTERM / SIGKILL
leave no temporary folder (or, for SIGKILL, one the next run removes) and no orphan worker."""

from __future__ import annotations

import fcntl
import importlib.util
import json
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from in_process import run_usecase_here as run_here
from test_run_usecase import earlier_results

from yafs_safetail.runs.experiment import REPOSITORY
from yafs_safetail.runs.output import OutputError, check_target, is_results_folder, refuse_protected

SCRIPT = REPOSITORY / "experiments" / "run_usecase.py"
TINY = ["--steps-scale", "0.02", "--redundancy", "1", "--no-figures", "--no-yafs-csv", "--quiet"]


def start(*args: str | Path, cwd: Path = REPOSITORY) -> subprocess.Popen[str]:
    env = {k: v for k, v in os.environ.items() if k != "YAFS_SAFETAIL_DEBUG"}
    return subprocess.Popen([sys.executable, str(SCRIPT), *map(str, args)], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def run(*args: str | Path, cwd: Path = REPOSITORY) -> subprocess.CompletedProcess[str]:
    process = start(*args, cwd=cwd)
    stdout, stderr = process.communicate(timeout=600)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def one_error_line(done: subprocess.CompletedProcess[str], *fragments: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in done.stderr, done.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def children_of(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def is_gone(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True
    return "\nState:\tZ" in status  # a zombie has ended; only its parent's bookkeeping is left


def lasting_children(process: subprocess.Popen, timeout_s: float = 120.0) -> list[int]:
    """The run's worker processes: children still there half a second after they were first seen
    (a short-lived helper the run starts, such as a git call, is not a worker); [] if the run
    ended first."""
    deadline = time.monotonic() + timeout_s
    while process.poll() is None:
        seen = set(children_of(process.pid))
        if seen:
            time.sleep(0.5)
            lasting = sorted(seen & set(children_of(process.pid)))
            if lasting:
                return lasting
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)
    return []


def wait_for(condition, timeout_s: float = 120.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def test_protected_folders_are_refused_in_process():
    for folder in (Path("/"), Path.home(), Path.cwd(), REPOSITORY, REPOSITORY.parent):
        with pytest.raises(OutputError, match="give a folder of its own"):
            refuse_protected(folder)
    assert refuse_protected(REPOSITORY / "results" / "uc1") == (REPOSITORY / "results" / "uc1").resolve()


@pytest.mark.parametrize("out", [".", ".."])
def test_out_dot_or_a_folder_holding_the_working_folder_is_refused(tmp_path, out):
    work = tmp_path / "work"
    work.mkdir()
    (work / "precious.txt").write_text("my notes\n")
    kept = snapshot(tmp_path)
    done = run("--uc", "1", "--out", out, *TINY, cwd=work)
    one_error_line(done, "--out", "working folder")
    assert snapshot(tmp_path) == kept


def test_a_folder_that_is_not_a_results_folder_is_never_written(tmp_path):
    foreign = tmp_path / "thesis"
    foreign.mkdir()
    (foreign / "chapter1.tex").write_text("\\section{Intro}\n")
    kept = snapshot(foreign)
    for extra in ([], ["--overwrite"]):
        done = run("--uc", "1", "--out", foreign, *TINY, *extra)
        one_error_line(done, "not a results folder")
    assert snapshot(foreign) == kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis"]


def test_an_earlier_run_is_replaced_only_with_overwrite(tmp_path):
    out = tmp_path / "run"
    first = run_here("--uc", "1", "--seed", "1", "--out", out, *TINY)  # (in this process: faster)
    assert first.returncode == 0, first.stderr
    assert is_results_folder(out)
    kept = snapshot(out)
    again = run("--uc", "1", "--seed", "2", "--out", out, *TINY)
    one_error_line(again, "holds an earlier run", "--overwrite")
    assert snapshot(out) == kept
    replaced = run_here("--uc", "1", "--seed", "2", "--out", out, *TINY, "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    assert snapshot(out) != kept and '"seed": 2' in (out / "run.json").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no lock, no temporary folder


def test_an_empty_folder_is_used(tmp_path):
    out = tmp_path / "made_for_it"
    out.mkdir()
    assert check_target(out, overwrite=False) == out.resolve()


def test_a_second_run_on_the_same_folder_fails_at_once(tmp_path):
    out = tmp_path / "run"
    with open(tmp_path / ".run.lock", "a+") as lock:  # what a running run holds
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        started = time.monotonic()
        done = run("--uc", "1", "--out", out, *TINY)
        one_error_line(done, "another run is writing there now")
        assert time.monotonic() - started < 60  # before any simulation
    assert not out.exists()


def test_sigterm_stops_workers_and_leaves_nothing_behind(tmp_path):
    out = tmp_path / "run"
    process = start("--uc", "1", "--out", out, "--steps-scale", "0.3", "--workers", "2",
                    "--no-figures", "--quiet")
    workers = lasting_children(process)
    assert workers, "the run ended before its worker started"
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 128 + signal.SIGTERM, stderr
    assert stderr.strip().splitlines()[-1] == "error: terminated; no partial results were kept"
    wait_for(lambda: all(is_gone(pid) for pid in workers), 30)
    assert list(tmp_path.iterdir()) == []


def test_sigkill_leaves_no_orphan_and_the_next_run_clears_its_folder(tmp_path):
    out = tmp_path / "run"
    process = start("--uc", "1", "--out", out, "--steps-scale", "0.3", "--workers", "2",
                    "--no-figures", "--quiet")
    workers = lasting_children(process)
    assert workers, "the run ended before its worker started"
    process.kill()
    process.communicate(timeout=60)
    wait_for(lambda: all(is_gone(pid) for pid in workers), 30)  # PR_SET_PDEATHSIG
    leftovers = [p.name for p in tmp_path.iterdir()]
    assert all(name.startswith(".run.") for name in leftovers)  # a killed run cannot clean up
    done = run("--uc", "1", "--out", out, *TINY)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def run_usecase_module():
    """The run command's module (experiments/run_usecase.py runs its main)."""
    return importlib.import_module("yafs_safetail.commands.run_usecase")


def test_the_default_folder_names_preset_seed_and_scale():
    module = run_usecase_module()
    assert module.parse_args(["--uc", "2", "--seed", "3"]).out_dir == Path("results/uc2-paper-s3")
    quick = module.parse_args(["--uc", "1", "--preset", "tuned", "--steps-scale", "0.1"])
    assert quick.out_dir == Path("results/uc1-tuned-s0-x0.1")
    faster = module.parse_args(["--uc", "1", "--learning-rate", "1e-3", "--steps-scale", "0.1"])
    assert faster.out_dir == Path("results/uc1-paper-lr0.001-s0-x0.1")
    assert faster.learning_rate == 1e-3
    text = module.parse_args(["--uc", "1", "--baseline-reading", "paper-text"])
    assert text.out_dir == Path("results/uc1-paper-paper-text-s0")
    q_style = module.parse_args(["--uc", "1", "--objective", "q-target", "--learning-rate", "3e-3"])
    assert q_style.out_dir == Path("results/uc1-paper-lr0.003-q-target-s0")


def test_the_default_folder_names_each_added_method(tmp_path):
    # A second policy's run must not stop at "holds an earlier run" of the first's.
    module = run_usecase_module()
    example = REPOSITORY / "examples" / "custom_policy" / "nearest_free.py"
    odd = tmp_path / "odd.py"  # a name that is no folder name as it stands
    odd.write_text("from yafs_safetail.methods import Policy\n\n"
                   "class Odd(Policy):\n    name = 'my/odd policy'\n")
    one = module.parse_args(["--uc", "1", "--method", f"{example}:NearestFree"])
    assert one.out_dir == Path("results/uc1-paper-s0+NearestFree")
    two = module.parse_args(["--uc", "1", "--steps-scale", "0.1", "--method", f"{example}:NearestFree",
                             "--method", f"Mine={example}:NearestFree", "--method", f"{odd}:Odd"])
    assert two.out_dir == Path("results/uc1-paper-s0-x0.1+NearestFree+Mine+my_odd_policy")
    # A run without --method keeps its name; --out is taken as given.
    assert module.parse_args(["--uc", "1"]).out_dir == Path("results/uc1-paper-s0")
    given = module.parse_args(["--uc", "1", "--method", f"{example}:NearestFree", "--out", "mine"])
    assert given.out_dir == Path("mine")


def test_the_default_folder_names_a_topology_other_than_the_papers(tmp_path, monkeypatch):
    module = run_usecase_module()
    topologies = REPOSITORY / "topologies"
    three = module.parse_args(["--uc", "1", "--topology", str(topologies / "3servers.json")])
    assert three.out_dir == Path("results/uc1-paper-3servers-s0")
    every_part = module.parse_args(["--uc", "2", "--preset", "tuned", "--learning-rate", "1e-3", "--seed", "4",
                                    "--steps-scale", "0.1", "--topology", str(topologies / "7servers.json")])
    assert every_part.out_dir == Path("results/uc2-tuned-lr0.001-7servers-s4-x0.1")
    # The paper's topology keeps the paper's name, however it is given: relative to the
    # project, or through a link.
    monkeypatch.chdir(REPOSITORY)
    relative = module.parse_args(["--uc", "1", "--topology", "topologies/paper_5servers.json"])
    assert relative.out_dir == Path("results/uc1-paper-s0")
    link = tmp_path / "mine.json"
    link.symlink_to(topologies / "paper_5servers.json")
    placement = str(REPOSITORY / "placements" / "paper_5servers.json")
    assert (module.parse_args(["--uc", "1", "--topology", str(link), "--placement", placement]).out_dir
            == Path("results/uc1-paper-s0"))
    # A copy elsewhere is another file: it may be edited, so its runs get their own folder.
    copy = tmp_path / "paper_5servers.json"
    copy.write_bytes((topologies / "paper_5servers.json").read_bytes())
    assert (module.parse_args(["--uc", "1", "--topology", str(copy), "--placement", str(copy)]).out_dir
            == Path("results/uc1-paper-paper_5servers-s0"))


@pytest.mark.parametrize(("args", "fragments"), [
    (["--steps-scale", "0.01"], ["100 training requests", "κ = 128", "--steps-scale 0.0128 or more"]),
    (["--steps-scale", "1000"], ["GB of results", "--force"]),
    (["--steps-scale", "1e9"], ["GB of results", "--force"]),
])
def test_budgets_too_small_or_too_large_are_refused_before_anything_runs(tmp_path, args, fragments):
    done = run("--uc", "1", "--out", tmp_path / "run", *args)
    one_error_line(done, *fragments)
    assert list(tmp_path.iterdir()) == []


def test_too_few_test_requests_are_refused_even_without_training(tmp_path):
    policy = tmp_path / "policy.keras"  # a saved policy: no training, so only the test budget counts
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.runs.budget import BudgetError, check_budget
    from yafs_safetail.runs.experiment import ExperimentConfig

    full = get_preset("paper", 1)
    with pytest.raises(BudgetError, match="8 test requests, fewer than 10"):
        check_budget(ExperimentConfig(policy=policy, steps_scale=0.002), full, full, 8, 11)


def test_a_large_forced_budget_warns_about_the_disk(caplog):
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.runs.budget import check_budget
    from yafs_safetail.runs.experiment import ExperimentConfig

    full = get_preset("paper", 1)
    big = get_preset("paper", 1, train_steps=2_000_000)
    with caplog.at_level(logging.WARNING, logger="yafs_safetail.runs.budget"):
        check_budget(ExperimentConfig(steps_scale=200, force=True, write_yafs_csv=True), full, big, 800_000, 11)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 2 and "--steps-scale 200 will write about" in warnings[0]
    # 2e6 training requests, 2e6 + 8.8e6 request rows at the measured speeds: about 41 min.
    assert "--steps-scale 200 will take about 41 min" in warnings[1]


def test_a_default_budget_gives_no_warning(caplog):
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.runs.budget import check_budget
    from yafs_safetail.runs.experiment import ExperimentConfig

    full = get_preset("paper", 1)
    with caplog.at_level(logging.DEBUG, logger="yafs_safetail.runs.budget"):
        check_budget(ExperimentConfig(), full, full, full.test_steps, 11)
    assert not caplog.records


def test_bad_policy_files_and_slow_links_are_one_line_errors(tmp_path):
    trained = tmp_path / "trained"
    assert run_here("--uc", "1", "--out", trained, *TINY).returncode == 0
    policy = trained / "policy.keras"
    truncated = tmp_path / "truncated.keras"
    truncated.write_bytes(policy.read_bytes()[:20_000])
    (tmp_path / "truncated.keras.json").write_bytes((trained / "policy.keras.json").read_bytes())
    one_error_line(run("--uc", "1", "--policy", truncated, "--out", tmp_path / "a", *TINY),
                   "truncated.keras", "not a complete .keras file")
    one_error_line(run("--uc", "2", "--policy", policy, "--out", tmp_path / "b", "--steps-scale", "0.03",
                       "--quiet"), "trained for use case 1, not 2")
    topology = json.loads((REPOSITORY / "topologies" / "paper_5servers.json").read_text())
    for link in topology["link"]:
        link["BW"] = 0.0005  # 4 kbit/s: a request takes minutes
    slow = tmp_path / "slow.json"
    slow.write_text(json.dumps(topology))
    done = run("--uc", "1", "--topology", slow, "--placement", REPOSITORY / "placements" / "paper_5servers.json",
               "--out", tmp_path / "c", *TINY)
    one_error_line(done, "step_interval_s=60", "--step-interval-s")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists() and not (tmp_path / "c").exists()


def test_only_this_tools_files_are_ever_removed(tmp_path):
    """A user's file named like our lock, or a folder named like our temporary folders, is
    left alone: only what carries the tool's marker is removed."""
    mine = tmp_path / ".run.lock"
    mine.write_text("my notes\n")
    done = run("--uc", "1", "--out", tmp_path / "run", *TINY)
    one_error_line(done, ".run.lock", "not a yafs-safetail lock")
    assert mine.read_text() == "my notes\n"
    mine.unlink()
    lookalike = tmp_path / ".run.partial-mine"
    lookalike.mkdir()
    (lookalike / "data.txt").write_text("keep\n")
    done = run_here("--uc", "1", "--out", tmp_path / "run", *TINY)
    assert done.returncode == 0, done.stderr
    assert (lookalike / "data.txt").read_text() == "keep\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".run.partial-mine", "run"]
    assert not (tmp_path / "run" / ".yafs-safetail-partial").exists()


def test_more_servers_than_safetail_supports_is_one_line(tmp_path):
    topology = json.loads((REPOSITORY / "topologies" / "7servers.json").read_text())
    access_point = next(e["id"] for e in topology["entity"] if e["type"] == "access_point")
    template = next(e for e in topology["entity"] if e["type"] == "edge_server")
    next_id = max(e["id"] for e in topology["entity"]) + 1
    for extra in range(5):
        topology["entity"].append(dict(template, id=next_id + extra, load_device=extra))
        topology["link"].append({"s": access_point, "d": next_id + extra, "BW": 2.5, "PR": 0.0, "condition": 2})
    servers = [e["id"] for e in topology["entity"] if e["type"] == "edge_server"]
    (tmp_path / "t12.json").write_text(json.dumps(topology))
    (tmp_path / "p12.json").write_text(json.dumps({"initialAllocation": [
        {"module_name": "EdgeService", "app": "SafeTail", "id_resource": i} for i in servers]}))
    done = subprocess.run([sys.executable, str(REPOSITORY / "experiments" / "run_usecase.py"), "--uc", "1",
                           "--topology", str(tmp_path / "t12.json"), "--placement", str(tmp_path / "p12.json"),
                           "--out", str(tmp_path / "out"), "--steps-scale", "0.05"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "t12.json: entity: 12 edge servers; SafeTail supports 1 to 10" in done.stderr
    assert not (tmp_path / "out").exists()


def test_an_empty_file_named_like_the_lock_is_not_taken(tmp_path):
    """Only a lock this run made, or one carrying the marker, is used and removed: an empty
    file of the user's with the lock's name stays."""
    mine = tmp_path / ".run.lock"
    mine.touch()
    done = run("--uc", "1", "--out", tmp_path / "run", *TINY)
    one_error_line(done, ".run.lock", "not a yafs-safetail lock")
    assert mine.is_file() and mine.read_text() == "" and not (tmp_path / "run").exists()


def test_a_publish_killed_between_its_renames_loses_nothing(tmp_path, monkeypatch):
    from yafs_safetail.runs import output

    target = tmp_path / "run"
    kept = earlier_results(target)
    renames = []
    real_replace = os.replace

    def replace_then_die(src, dst):  # type: ignore[no-untyped-def]
        real_replace(src, dst)
        renames.append(dst)
        if len(renames) == 1:  # the earlier run is aside, the new one not yet in place
            raise KeyboardInterrupt

    staged = output.StagedOutput(target, overwrite=True)
    with pytest.raises(KeyboardInterrupt):
        with staged as staging:
            (staging / "run.json").write_text("{}")
            (staging / "requests.csv").write_text("new\n")
            monkeypatch.setattr(output.os, "replace", replace_then_die)
            staged.publish()
    monkeypatch.setattr(output.os, "replace", real_replace)
    assert not target.exists()  # the kill's window: the earlier run is aside
    # The next run on the target (even one that fails) puts the earlier run back first.
    with pytest.raises(OutputError, match="holds an earlier run"):
        with output.StagedOutput(tmp_path / "run", overwrite=False):
            pass
    assert snapshot(target) == kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_an_earlier_run_aside_is_kept_when_something_else_took_the_target(tmp_path, monkeypatch):
    # A publish killed between its renames, then someone puts a file where the results were:
    # the earlier run cannot go back, and it must not be removed either.
    from yafs_safetail.runs import output

    target = tmp_path / "run"
    kept = earlier_results(target)
    real_replace = os.replace
    renames = []

    def replace_then_die(src, dst):  # type: ignore[no-untyped-def]
        real_replace(src, dst)
        renames.append(dst)
        raise KeyboardInterrupt

    staged = output.StagedOutput(target, overwrite=True)
    with pytest.raises(KeyboardInterrupt):
        with staged as staging:
            (staging / "run.json").write_text("{}")
            monkeypatch.setattr(output.os, "replace", replace_then_die)
            staged.publish()
    monkeypatch.setattr(output.os, "replace", real_replace)
    target.write_text("a user's file\n")
    with pytest.raises(OutputError):
        with output.StagedOutput(target, overwrite=False):
            pass
    aside = list(tmp_path.glob(".run.previous-*/run"))
    assert len(aside) == 1 and snapshot(aside[0]) == kept
    assert target.read_text() == "a user's file\n"


def test_discarding_a_checkpoint_removes_only_the_tools_files(tmp_path):
    from yafs_safetail.runs.checkpoint import (
        CHECKPOINT_MARKER,
        checkpoint_folder,
        discard_checkpoint,
    )

    target = tmp_path / "run"
    folder = checkpoint_folder(target)
    folder.mkdir()
    (folder / CHECKPOINT_MARKER).touch()
    (folder / "training.pickle").write_bytes(b"x")
    (folder / "notes.txt").write_text("mine\n")
    discard_checkpoint(target)
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt"]
    (folder / "notes.txt").unlink()
    (folder / CHECKPOINT_MARKER).touch()
    discard_checkpoint(target)
    assert not folder.exists()  # nothing else inside: the folder goes too


@pytest.mark.slow  # many kills at random moments; test_sigkill_leaves_no_orphan... runs one
def test_sigkill_at_random_points_never_loses_the_earlier_run(tmp_path):
    # Fault injection: a run replacing an earlier one (--overwrite) is killed outright at
    # seeded random moments from start-up to the end. Whatever the moment, the target holds
    # the earlier run or the complete new one, and the next run leaves nothing else behind.
    target = tmp_path / "run"
    kept = earlier_results(target)
    args = ("--uc", "1", "--out", target, "--overwrite", *TINY, "--workers", "2",
            "--checkpoint-every-s", "0")
    started = time.monotonic()
    timing = run("--uc", "1", "--out", tmp_path / "timing", *TINY)
    assert timing.returncode == 0, timing.stderr
    full_s = time.monotonic() - started
    for delay_s in np.random.default_rng(2026).uniform(0.2, 1.1 * full_s, size=4):
        process = start(*args)
        time.sleep(delay_s)
        process.kill()
        process.communicate(timeout=60)
        if not target.exists():  # killed between publish's two renames: the earlier run is aside
            aside = list(tmp_path.glob(".run.previous-*/run"))
            assert len(aside) == 1 and snapshot(aside[0]) == kept, f"killed after {delay_s:.2f} s"
            continue  # the next run puts it back first
        if is_results_folder(target) and snapshot(target) != kept:
            break  # the run finished before the kill: the new results are complete
        assert snapshot(target) == kept, f"killed after {delay_s:.2f} s"
    done = run(*args)
    assert done.returncode == 0, done.stderr
    assert is_results_folder(target) and snapshot(target) != kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run", "timing"]


@pytest.fixture
def umask_027():
    """A umask other than the usual 022 (group may read, others nothing), restored after."""
    previous = os.umask(0o027)
    yield
    os.umask(previous)


def modes(folder: Path) -> dict[str, int]:
    """Permission bits of ``folder`` and of everything in it, by relative path."""
    return {str(p.relative_to(folder)): p.stat().st_mode & 0o777 for p in [folder, *folder.rglob("*")]}


def test_a_published_folder_has_the_umasks_permissions_and_staging_stays_private(tmp_path, umask_027):
    from yafs_safetail.runs import output

    staged = output.StagedOutput(tmp_path / "run")
    with staged as staging:
        assert staging.stat().st_mode & 0o777 == 0o700  # nobody else reads a run being written
        (staging / "run.json").write_text("{}")
        staged.publish()
    assert modes(tmp_path / "run") == {".": 0o750, "run.json": 0o640}


def test_a_run_in_a_shared_place_is_readable_by_others(tmp_path):
    out = tmp_path / "run"
    env = {k: v for k, v in os.environ.items() if k != "YAFS_SAFETAIL_DEBUG"}
    done = subprocess.run([sys.executable, str(SCRIPT), "--uc", "1", "--out", str(out), "--steps-scale", "0.02",
                           "--redundancy", "1", "--yafs-csv", "--quiet"],
                          cwd=REPOSITORY, env=env, capture_output=True, text=True, timeout=600, umask=0o022)
    assert done.returncode == 0, done.stderr
    found = modes(out)
    assert {"policy.keras", "policy.keras.json", "summary.md", "figures", "yafs"} <= set(found)
    folders = {name for name in found if (out / name).is_dir()}
    assert {name: found[name] for name in folders} == dict.fromkeys(folders, 0o755)
    assert {name: found[name] for name in set(found) - folders} == dict.fromkeys(set(found) - folders, 0o644)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no lock, staging or checkpoint left
