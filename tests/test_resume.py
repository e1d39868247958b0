"""--resume: an interrupted training continues from its checkpoint and the results files are
byte for byte those of an uninterrupted run, wherever the run was stopped; a checkpoint that
does not fit is one line; only the tool's own checkpoint folder is ever replaced or removed."""

from __future__ import annotations

import dataclasses
import pickle
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest
from in_process import run_usecase_here as run_here
from test_run_safety import one_error_line, run, snapshot, start, wait_for

from yafs_safetail.methods.safetail.presets import get_preset, scaled_steps
from yafs_safetail.runs import checkpoint as checkpoint_module
from yafs_safetail.runs.checkpoint import CHECKPOINT_FILE, checkpoint_folder
from yafs_safetail.runs.experiment import CHECKPOINT_CHUNK_STEPS, ExperimentConfig, run_experiment

#: A budget whose training phase has several checkpoint chances (one per 100 requests).
SMALL = ["--steps-scale", "0.05", "--redundancy", "1", "--no-figures", "--quiet", "--workers", "1"]
RESULT_FILES = ("requests.csv", "summary.csv", "summary.md", "policy.keras", "policy.keras.json")


def results_of(folder: Path) -> dict[str, bytes]:
    return {name: (folder / name).read_bytes() for name in RESULT_FILES}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> dict[str, bytes]:
    out = tmp_path_factory.mktemp("uninterrupted") / "run"
    done = run_here("--uc", "1", "--out", out, *SMALL)
    assert done.returncode == 0, done.stderr
    assert not checkpoint_folder(out).exists()  # gone once the results are in place
    return results_of(out)


def stopped_by_sigterm(out: Path, attempts: int = 3) -> str:
    """Start a run to ``out``, SIGTERM it once its first checkpoint is on disk, and return its
    stderr. On a loaded machine this test process may be descheduled long enough for the small
    run to finish first (exit 0, or killed by the signal's default action while exiting);
    that run's own folder is then removed and it is tried again."""
    saved = checkpoint_folder(out) / CHECKPOINT_FILE
    for _ in range(attempts):
        process = start("--uc", "1", "--out", out, *SMALL, "--checkpoint-every-s", "0")
        wait_for(lambda running=process: saved.is_file() or running.poll() is not None)
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=120)
        if process.returncode == 128 + signal.SIGTERM:
            return stderr
        assert process.returncode in (0, -signal.SIGTERM), stderr
        shutil.rmtree(out, ignore_errors=True)  # the finished run's own folder
    pytest.fail(f"the run finished before it could be stopped, {attempts} times; raise SMALL's budget")


def test_sigterm_mid_training_then_resume_gives_the_uninterrupted_files(tmp_path, uninterrupted):
    out = tmp_path / "run"
    saved = checkpoint_folder(out) / CHECKPOINT_FILE
    stderr = stopped_by_sigterm(out)
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("error: terminated") and "--resume" in last, last
    assert not out.exists() and saved.is_file()
    # The same command again with --resume (in this process: only the stop needs a subprocess).
    done = run_here("--uc", "1", "--out", out, *SMALL, "--checkpoint-every-s", "0", "--resume")
    assert done.returncode == 0, done.stderr
    assert results_of(out) == uninterrupted
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


class _Stop(KeyboardInterrupt):
    """Stands for a kill: raised by the fault injector after a chosen checkpoint."""


@pytest.mark.parametrize("stop_after", [1, 4, "last"])
def test_stopped_after_any_checkpoint_resumes_to_the_same_results(tmp_path, monkeypatch, stop_after):
    # In process, so the kill lands exactly after the chosen checkpoint (the first, a middle
    # one, or the one written when training ends, which resumes straight into the test phase).
    config = ExperimentConfig(use_case=1, out_dir=tmp_path / "run", steps_scale=0.05,
                              redundancy_levels=(1,), figures=False, progress=False, workers=1,
                              checkpoint_every_s=0.0)
    reference = run_experiment(dataclasses.replace(config, out_dir=tmp_path / "reference",
                                                   checkpoint_every_s=None))
    train_steps = scaled_steps(get_preset("paper", 1).train_steps, 0.05)
    assert train_steps > 4 * CHECKPOINT_CHUNK_STEPS  # room for a middle checkpoint
    written: list[int] = []
    real_write = checkpoint_module.write_checkpoint

    def write_then_stop(target, checkpoint):  # type: ignore[no-untyped-def]
        real_write(target, checkpoint)
        next_step = checkpoint.methods["SafeTail"].next_step
        written.append(next_step)
        if (stop_after == "last" and next_step == train_steps) or len(written) == stop_after:
            raise _Stop

    monkeypatch.setattr(checkpoint_module, "write_checkpoint", write_then_stop)
    with pytest.raises(_Stop) as stopped:
        run_experiment(config)
    assert any("--resume" in note for note in getattr(stopped.value, "__notes__", []))
    assert not config.out_dir.exists()
    monkeypatch.setattr(checkpoint_module, "write_checkpoint", real_write)
    resumed = run_experiment(dataclasses.replace(config, resume=True))
    assert written[-1] > 0
    assert results_of(resumed.out_dir) == results_of(reference.out_dir)
    assert not checkpoint_folder(config.out_dir).exists()


def test_the_checkpoint_restores_the_learner_exactly(tmp_path):
    from yafs_safetail.methods.safetail.learner import SafeTailLearner

    config = dataclasses.replace(get_preset("tuned", 1), kappa=8, batch_size=4)
    rng = np.random.default_rng(5)
    states = rng.random((40, 6), dtype=np.float32)
    rewards = -rng.random(40)

    def feed(learner: SafeTailLearner, rows: range) -> list[int]:
        actions = []
        for i in rows:
            action = learner.act(states[i], explore=True)
            learner.observe(states[i], action, float(rewards[i]))
            actions.append(action)
        return actions

    straight = SafeTailLearner(3, 6, config, seed=9)
    first = feed(straight, range(20))
    state = pickle.loads(pickle.dumps(straight.training_state()))
    rest = feed(straight, range(20, 40))
    restored = SafeTailLearner(3, 6, config, seed=9)
    restored.restore_training_state(state)
    assert feed(restored, range(20, 40)) == rest
    assert first  # the first half trained too (κ = 8: two rounds)
    for a, b in zip(straight.model.get_weights(), restored.model.get_weights(), strict=True):
        assert np.array_equal(a, b)
    assert straight.n_training_rounds == restored.n_training_rounds == 5


def test_resume_without_a_checkpoint_is_one_line(tmp_path):
    one_error_line(run("--uc", "1", "--out", tmp_path / "run", *SMALL, "--resume"),
                   "--resume", "no checkpoint")


def test_resume_with_other_options_is_one_line_and_keeps_the_checkpoint(tmp_path):
    out = tmp_path / "run"
    stopped_by_sigterm(out)
    kept = snapshot(checkpoint_folder(out))
    one_error_line(run("--uc", "1", "--seed", "7", "--out", out, *SMALL, "--resume"),
                   "--resume", "another configuration")
    assert snapshot(checkpoint_folder(out)) == kept


def test_a_foreign_folder_with_the_checkpoint_name_is_refused_and_kept(tmp_path):
    out = tmp_path / "run"
    foreign = checkpoint_folder(out)
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    one_error_line(run("--uc", "1", "--out", out, *SMALL), "not a yafs-safetail checkpoint")
    assert (foreign / "notes.txt").read_text() == "mine" and not out.exists()


def test_a_truncated_checkpoint_is_one_line(tmp_path):
    out = tmp_path / "run"
    folder = checkpoint_folder(out)
    folder.mkdir()
    (folder / checkpoint_module.CHECKPOINT_MARKER).touch()
    (folder / CHECKPOINT_FILE).write_bytes(pickle.dumps((1, "x"))[:5])
    one_error_line(run("--uc", "1", "--out", out, *SMALL, "--resume"), "not a checkpoint")


def test_resume_needs_a_training_run(tmp_path):
    one_error_line(run("--uc", "1", "--out", tmp_path / "run", *SMALL, "--yafs-csv", "--resume"),
                   "--resume", "--yafs-csv")


def test_the_checkpoint_is_gone_before_the_results_appear(tmp_path, monkeypatch):
    # A kill right after the results folder appears (a campaign then skips the finished run)
    # must not leave its checkpoint behind for ever: it goes before the rename.
    from yafs_safetail.runs.output import StagedOutput

    seen: list[bool] = []
    real_publish = StagedOutput.publish

    def publish(self):  # type: ignore[no-untyped-def]
        seen.append(checkpoint_folder(self.target).exists())
        real_publish(self)

    monkeypatch.setattr(StagedOutput, "publish", publish)
    config = ExperimentConfig(use_case=1, out_dir=tmp_path / "run", steps_scale=0.02,
                              redundancy_levels=(1,), figures=False, progress=False, workers=1,
                              checkpoint_every_s=0.0)
    run_experiment(config)
    assert seen == [False] and (tmp_path / "run" / "requests.csv").is_file()


def test_a_run_stopped_by_a_policys_bug_leaves_no_checkpoint(tmp_path):
    # Later chooses well on the first requests (so it passes the check at run start) and
    # returns no server from request 20 on: found in its test simulation, after SafeTail's
    # training wrote its checkpoint. --resume could not get past it, and fixing the file gives
    # another run id: the checkpoint would only be a hidden folder of megabytes.
    from yafs_safetail.methods.policy import PolicyError
    from yafs_safetail.methods.registry import UserMethod

    written: list[Path] = []
    config = ExperimentConfig(use_case=1, out_dir=tmp_path / "run", steps_scale=0.02,
                              redundancy_levels=(1,), figures=False, progress=False, workers=1,
                              checkpoint_every_s=0.0,
                              methods=(UserMethod(f"{Path(__file__).parent / 'bad_policies.py'}:Later"),))
    real_write = checkpoint_module.write_checkpoint

    def write(target, checkpoint):  # type: ignore[no-untyped-def]
        real_write(target, checkpoint)
        written.append(checkpoint_folder(target))

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(checkpoint_module, "write_checkpoint", write)
        with pytest.raises(PolicyError, match="Later: invalid subset"):
            run_experiment(config)
    assert written and all(folder == checkpoint_folder(config.out_dir) for folder in written)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("error", "resumable"), [
    (KeyboardInterrupt(), True), (OSError(28, "No space left on device"), True),
    (ChildProcessError("worker killed"), True), (ValueError("bad policy"), False),
    (IndexError("a bug"), False),
])
def test_only_a_stop_from_outside_keeps_the_checkpoint(error, resumable):
    assert checkpoint_module.resumable_after(error) is resumable


def test_a_sigterm_that_surfaced_as_another_exception_still_keeps_the_checkpoint():
    # A SIGTERM inside library code can come out as, say, the ImportError of the import it cut
    # short: the process's flag, not the exception's type, says the run was stopped from outside.
    from yafs_safetail.stopping import Terminated, clear_terminating, raise_terminated

    try:
        with pytest.raises(Terminated):
            raise_terminated(signal.SIGTERM, None)
        assert checkpoint_module.resumable_after(ImportError("cut short by the signal")) is True
    finally:
        clear_terminating()
    assert checkpoint_module.resumable_after(ImportError("a missing module")) is False
