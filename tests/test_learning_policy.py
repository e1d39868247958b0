"""A user's learning policy (``--method file.py:Class``, a LearningPolicy) gets what SafeTail
gets: a training phase on the same requests, its saved file, its run.json fields, checkpoints
and ``--resume`` giving the results of an uninterrupted run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_run_safety import one_error_line, run

from yafs_safetail.methods.learning import LearningPolicy
from yafs_safetail.methods.registry import UserMethod
from yafs_safetail.runs import checkpoint as checkpoint_module
from yafs_safetail.runs.checkpoint import checkpoint_folder
from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment

LEARNER = Path(__file__).resolve().parent / "counting_learner.py"
SPEC = f"{LEARNER}:CountingLearner"
SAVED = "CountingLearner.policy"
#: 200 training requests (two checkpoint chunks), 80 test requests.
TINY = ["--steps-scale", "0.02", "--redundancy", "1", "--no-figures", "--quiet"]
COMPARED = ("requests.csv", "summary.csv", "summary.md", "policy.keras", "policy.keras.json", SAVED)


def results_of(folder: Path) -> dict[str, object]:
    found: dict[str, object] = {name: (folder / name).read_bytes() for name in COMPARED}
    found["run.json"] = {k: v for k, v in json.loads((folder / "run.json").read_text()).items()
                         if k != "command"}
    return found


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("learner") / "run"
    done = run("--uc", "1", "--out", out, "--method", SPEC, "--workers", "2", *TINY)
    assert done.returncode == 0, done.stderr
    return out


def test_a_users_learner_trains_tests_and_is_saved_like_safetail(uninterrupted):
    requests = pd.read_csv(uninterrupted / "requests.csv")
    counts = requests[requests["method"] == "CountingLearner"].groupby("phase").size().to_dict()
    safetail = requests[requests["method"] == "SafeTail"].groupby("phase").size().to_dict()
    assert counts == safetail == {"train": 200, "test": 80}
    test = requests[(requests["method"] == "CountingLearner") & (requests["phase"] == "test")]
    assert test["servers"].nunique() == 1  # greedy after training: its one best server
    run_json = json.loads((uninterrupted / "run.json").read_text())
    assert "CountingLearner" in run_json["methods"] and run_json["counting_learner_requests"] == 200
    assert run_json["preset"] == "paper" and run_json["policy_source"] == "policy.keras"
    saved = json.loads((uninterrupted / SAVED).read_text())
    assert sum(saved["requests"]) == 200
    assert "UC1 CountingLearner: 200 requests counted" in (uninterrupted / "run.log").read_text()


def test_the_saved_learner_loads_back_to_what_it_learned(uninterrupted):
    policy = UserMethod(SPEC).make_learner(5, np.random.default_rng(0))
    assert isinstance(policy, LearningPolicy)
    policy.load(uninterrupted / SAVED)
    assert policy.requests.sum() == 200  # type: ignore[attr-defined]
    policy.begin_phase("test")
    chosen = policy.choose(None)
    mean_s = policy.latency_sum_s / np.maximum(policy.requests, 1)  # type: ignore[attr-defined]
    assert chosen == [int(np.argmin(np.where(policy.requests > 0, mean_s, np.inf)))]  # type: ignore[attr-defined]


class _Stop(KeyboardInterrupt):
    """Stands for a kill, right after the chosen checkpoint."""


def test_stopped_mid_training_of_the_users_learner_resumes_to_the_same_results(
        tmp_path, monkeypatch, uninterrupted):
    config = ExperimentConfig(use_case=1, out_dir=tmp_path / "run", steps_scale=0.02,
                              redundancy_levels=(1,), figures=False, progress=False, workers=1,
                              checkpoint_every_s=0.0, methods=(UserMethod(SPEC),))
    real_write = checkpoint_module.write_checkpoint
    stood: list[dict[str, int]] = []

    def write_then_stop(target, checkpoint):  # type: ignore[no-untyped-def]
        real_write(target, checkpoint)
        stood.append({name: part.next_step for name, part in checkpoint.methods.items()})
        if stood[-1].get("CountingLearner", 0) == 100:  # SafeTail trained, the learner half-way
            raise _Stop

    monkeypatch.setattr(checkpoint_module, "write_checkpoint", write_then_stop)
    with pytest.raises(_Stop):
        run_experiment(config)
    assert stood[-1] == {"SafeTail": 200, "CountingLearner": 100}
    monkeypatch.setattr(checkpoint_module, "write_checkpoint", real_write)
    resumed = run_experiment(ExperimentConfig(**{**config.__dict__, "resume": True}))
    assert "CountingLearner train: resumed from the checkpoint at request 100" in (
        resumed.out_dir / "run.log").read_text()
    assert results_of(resumed.out_dir) == results_of(uninterrupted)
    assert not checkpoint_folder(config.out_dir).exists()


def test_a_users_learner_with_a_saved_safetail_is_one_line(tmp_path, uninterrupted):
    one_error_line(run("--uc", "1", "--out", tmp_path / "run", "--policy",
                       uninterrupted / "policy.keras", "--method", SPEC, *TINY),
                   "--method", "training phase", "--policy")
