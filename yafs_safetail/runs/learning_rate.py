"""Choose the ``paper`` preset's learning rate by a rule fixed before looking (docs/calibration.md,
rule 3).

Table I's rates (1e-7 / 1e-6 / 1e-7) cannot move the network within the paper's 50·β steps
(docs/deviations.md D6), so ``paper`` departs from them, but only by this rule: per use case,
the rate of :data:`RATE_GRID` whose greedy policy earns the highest mean Eq. 5 reward over the
test requests of the learner-calibration seeds, at full budget, in the calibrated world; ties go
to the smaller rate. The scorecard's numbers never enter the choice.

Every run also records its greedy policy's share of test requests whose Eq. 5 reward is exactly
0 and its access rate: what §III's target vector trains toward (docs/calibration.md, "The
spec owner's decision"). ``criterion="zero-share"`` chooses by that share instead (an
exploration on the calibration seeds, not rule 3).
"""

from __future__ import annotations

import concurrent.futures
import datetime
import json
import logging
import multiprocessing
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

import yafs_safetail
from yafs_safetail import results, versions
from yafs_safetail.defaults import LEARNING_RATE_GRID
from yafs_safetail.edge.calibration import seed_set
from yafs_safetail.edge.published import USE_CASES as PUBLISHED_USE_CASES
from yafs_safetail.methods.registry import SAFETAIL
from yafs_safetail.runs.workers import end_with_parent

#: The candidate rates, smallest first (a log grid around Adam's usual 1e-3).
RATE_GRID = LEARNING_RATE_GRID
USE_CASES = PUBLISHED_USE_CASES
RATES_FILE = "learning_rates.csv"
CHOICE_FILE = "learning_rates.json"
#: What a rate is chosen by: rule 3's mean Eq. 5 test reward, or the share of test rewards of
#: exactly 0 (the optimum of §III's target vector).
CRITERIA = {"mean-reward": "reward", "zero-share": "zero_share"}


class LearningRateRunError(ValueError):
    """A bad setting of the learning-rate rule (one line naming it)."""


@dataclass(frozen=True)
class LearningRateConfig:
    """What the rule depends on.

    Attributes:
        use_cases: the use cases to choose a rate for.
        rates: the candidate rates.
        seeds: learner-calibration seeds (default: ``seed_sets.json``).
        steps_scale: fraction of the full budget (1: the rule as written; less: a quick look).
        workers: runs in parallel (separate processes).
        out_dir: where the per-run rewards and the choice go.
        command: the command line, recorded in the provenance.
        criterion: one of :data:`CRITERIA` (``"mean-reward"``: rule 3 as written).
    """

    use_cases: tuple[int, ...] = USE_CASES
    rates: tuple[float, ...] = RATE_GRID
    seeds: tuple[int, ...] = field(default_factory=lambda: tuple(seed_set("learner_calibration")))
    steps_scale: float = 1.0
    workers: int = 2
    out_dir: Path = Path("results/learning-rate")
    command: str = ""
    criterion: str = "mean-reward"


def test_reward(use_case: int, rate: float, seed: int, steps_scale: float) -> dict[str, float]:
    """One default run of ``use_case`` at ``rate``: the greedy policy's mean Eq. 5 reward over
    its test requests (``reward``), the share of them earning exactly 0 (``zero_share``) and its
    access rate (``access_rate``)."""
    import tensorflow as tf

    from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment

    # Every run builds a new learner and so a new training-round function; TensorFlow warns
    # about the retracing that follows, which is expected here.
    tf.get_logger().setLevel("ERROR")
    with tempfile.TemporaryDirectory(prefix="yafs-safetail-rate-") as scratch:
        out = Path(scratch) / "run"
        run_experiment(ExperimentConfig(
            use_case=use_case, preset="paper", seed=seed, out_dir=out, steps_scale=steps_scale,
            write_yafs_csv=False, figures=False, progress=False, workers=1, learning_rate=rate,
            redundancy_levels=(1,),  # the baselines do not enter the rule: the fewest that run
        ))
        rows = pd.read_csv(out / "requests.csv", usecols=["method", "phase", "reward", "access_rate"])
    test = rows[(rows["method"] == SAFETAIL) & (rows["phase"] == "test")]
    return {"reward": float(test["reward"].mean()), "zero_share": float((test["reward"] == 0.0).mean()),
            "access_rate": float(test["access_rate"].mean())}


def choose(rewards: pd.DataFrame, column: str = "reward") -> dict[int, float]:
    """Per use case, the rate with the highest mean of ``column`` over seeds (rule 3: the mean
    reward); ties to the smaller."""
    means = rewards.groupby(["use_case", "rate"], sort=True)[column].mean().reset_index()
    chosen = {}
    for use_case, group in means.groupby("use_case", sort=True):
        best = group.sort_values([column, "rate"], ascending=[False, True], kind="stable").iloc[0]
        chosen[int(use_case)] = float(best["rate"])
    return chosen


def choose_learning_rates(config: LearningRateConfig,
                          log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the rule; returns the contents of ``learning_rates.json`` (also written)."""
    if log is None:
        log = logging.getLogger(__name__).info
    if not config.seeds or len(set(config.seeds)) != len(config.seeds):
        raise LearningRateRunError(f"--seeds: give distinct seeds, got {list(config.seeds)}")
    if config.criterion not in CRITERIA:
        raise LearningRateRunError(f"--criterion: expected one of {', '.join(CRITERIA)}, got {config.criterion!r}")
    started = time.perf_counter()
    jobs = [(uc, rate, seed) for uc in config.use_cases for rate in config.rates for seed in config.seeds]
    context = multiprocessing.get_context("spawn")
    # end_with_parent: a killed calibration leaves no worker process behind.
    with concurrent.futures.ProcessPoolExecutor(config.workers, mp_context=context,
                                                initializer=end_with_parent) as pool:
        futures = [pool.submit(test_reward, uc, rate, seed, config.steps_scale) for uc, rate, seed in jobs]
        rows = []
        for (uc, rate, seed), future in zip(jobs, futures, strict=True):
            rows.append({"use_case": uc, "rate": rate, "seed": seed, **future.result()})
            log(f"UC{uc} rate {rate:g} seed {seed}: mean test reward {rows[-1]['reward']:.4f}, "
                f"zero share {rows[-1]['zero_share']:.3f}, access {rows[-1]['access_rate']:.3f}")
    rewards = pd.DataFrame(rows)
    chosen = choose(rewards, CRITERIA[config.criterion])
    config.out_dir.mkdir(parents=True, exist_ok=True)
    results.write_text_atomic(config.out_dir / RATES_FILE, rewards.to_csv(index=False))
    document = {
        "learning_rates": {str(uc): rate for uc, rate in chosen.items()},
        "provenance": {
            "rule": ("docs/calibration.md, rule 3: highest mean Eq. 5 test reward of the greedy "
                     "policy over the learner-calibration seeds; ties to the smaller rate"
                     if config.criterion == "mean-reward" else
                     "not rule 3: the largest share of test rewards of exactly 0 of the greedy policy "
                     "over the learner-calibration seeds; ties to the smaller rate"),
            "criterion": config.criterion,
            "rates": list(config.rates),
            "seeds": list(config.seeds),
            "steps_scale": config.steps_scale,
            "mean_reward": {f"{uc}/{rate:g}": round(float(v), 6) for (uc, rate), v in
                            rewards.groupby(["use_case", "rate"])["reward"].mean().items()},
            "mean_zero_share": {f"{uc}/{rate:g}": round(float(v), 6) for (uc, rate), v in
                                rewards.groupby(["use_case", "rate"])["zero_share"].mean().items()},
            "mean_access_rate": {f"{uc}/{rate:g}": round(float(v), 6) for (uc, rate), v in
                                 rewards.groupby(["use_case", "rate"])["access_rate"].mean().items()},
            "date": datetime.date.today().isoformat(),
            "command": config.command,
            "package_version": yafs_safetail.__version__,
            **versions.run_json_fields(),
            "wall_s": round(time.perf_counter() - started, 1),
        },
    }
    results.write_text_atomic(config.out_dir / CHOICE_FILE, json.dumps(document, indent=2) + "\n")
    return document


def main_rows(document: dict[str, Any]) -> Sequence[str]:
    """The console lines of a finished choice."""
    return [f"UC{uc}: learning rate {rate:g}" for uc, rate in document["learning_rates"].items()]
