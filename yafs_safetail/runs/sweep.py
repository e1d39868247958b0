"""The contention world's sweeps: every method at every point of one axis.

Two axes share one loop (:func:`run_sweep`) and one table per point: the **load sweep** (the
offered load rises) and the **failure sweep** (each server's stationary probability of being
down rises at a fixed load; issue 31); ``runs.sweep_config`` says what each is
(``SweepConfig``, ``FailureSweepConfig``). Each point is a campaign run (``runs.sweep_points``).

At each point: a training world and a test world (independent streams, same users and
settings); each SafeTail learns on the training world at that point and is tested greedily;
every other method runs on the test world only. By default two SafeTails run side by side
(``sweep_learners.SAFETAIL_LEARNERS``): ``SafeTail``, the paper's learner (§III's target vector,
Eq. 5 against τ, copies sent all at once), and ``SafeTail-CA``, the contention-aware one (the
value learner that prices each copy by the jobs it joins, tied copies; docs/deviations.md D13).
All methods of a point see the same arrivals, per-request draws and outages (common random
numbers). Users' own policies (``--method FILE.py:CLASS``) run after the built-in methods, each
from its own generator (``methods.registry.method_rng``: the seed and its name); one that learns
(a ``LearningPolicy``) is first trained on a training world of its own, on the paper SafeTail's
budget (or ``--preset``'s). One row per (point, method) goes to the point's ``sweep.csv``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import pandas as pd

from yafs_safetail.contention.config import ContentionConfig
from yafs_safetail.contention.run import PolicyRun, run_policy, summarise
from yafs_safetail.contention.world import ContentionWorld
from yafs_safetail.methods.learning import TEST_PHASE, TRAIN_PHASE
from yafs_safetail.methods.policy import Policy
from yafs_safetail.methods.registry import UserMethod, make_baseline, method_rng
from yafs_safetail.methods.safetail.assemble import make_safetail
from yafs_safetail.methods.safetail.policy import SafeTailPolicy
from yafs_safetail.methods.safetail.presets import get_preset
from yafs_safetail.runs.sweep_config import ContentionSweep
from yafs_safetail.runs.sweep_learners import SafeTailVariant, training_requests


def _safetail_policy(world: ContentionWorld, variant: SafeTailVariant, seed: int) -> SafeTailPolicy:
    """One SafeTail of the sweep, built as every SafeTail is (``methods.safetail.assemble``). Its
    generators are seeded as a sweep with that learner alone seeds them, so its rows are the same
    whether the other SafeTail runs beside it or not."""
    config = replace(get_preset(variant.preset, world.use_case.number, train_steps=variant.train_requests),
                     objective=variant.learner, n_networks=variant.n_networks)
    return make_safetail(world.use_case, world.scenario, config, seed, metadata={"world": "contention"},
                         reward=variant.reward, dispatch=variant.dispatch, name=variant.name)


def _user_policy(config: ContentionSweep, value: float, method: UserMethod, test_config: ContentionConfig,
                 world: ContentionWorld, log: Callable[[str], None]) -> tuple[Policy, int]:
    """A user's policy at one point, with the requests it trained on: one that learns is trained
    first on a training world of its own (the same requests a SafeTail's has, read afresh) and
    tested in its test phase, as a run does."""
    rng = method_rng(config.base.seed, method.name)
    if not method.learns:
        return method.make(world.n_servers, rng), 0
    policy = method.make_learner(world.n_servers, rng)
    n_train = training_requests(config.preset or "paper", config.base.use_case, config.steps_scale)
    train_world = ContentionWorld(replace(test_config, phase="train", n_requests=n_train), world.inputs,
                                  world.scenario)
    policy.begin_phase(TRAIN_PHASE)
    trained = run_policy(train_world, policy, target=config.target)
    summary = policy.end_training()
    log(f"{config.axis.label} {value:g}: {method.name} trained on {n_train} requests in "
        f"{trained.wall_s:.1f} s{f' ({summary})' if summary else ''}")
    policy.begin_phase(TEST_PHASE)
    return policy, n_train


def _row_line(row: Mapping[str, Any]) -> str:
    """What a run's log says of one method at one point: its latency and copies, and with
    failures its success rate and energy."""
    line = (f"p50 {row['p50_s']:.3f} s  p99 {row['p99_s']:.3f} s  copies {row['mean_n_selected']:.2f}  "
            f"fallback {row['fallback_rate']:.3f}")
    if "failure_level" in row and "success_rate" in row:
        line += f"  success {row['success_rate']:.3f}  energy {row['energy_j_per_request']:.3g} J"
    return line


def run_sweep(config: ContentionSweep, log: Callable[[str], None] = lambda line: None,
              on_test_run: Callable[[float, PolicyRun], None] | None = None) -> pd.DataFrame:
    """Every (point, method) row of the sweep's table, points ascending, methods in the given
    order (the SafeTails first). ``on_test_run(value, run)`` sees each method's test run at
    each point, for what the table does not keep (its requests one by one)."""
    rows: list[dict[str, Any]] = []
    inputs = scenario = None
    label = config.axis.label
    for value in config.points:
        test_config = config.point_world(value)
        test_world = ContentionWorld(test_config, inputs, scenario)
        inputs, scenario = test_world.inputs, test_world.scenario
        policies: list[tuple[Policy, int]] = []
        for variant in config.safetails:
            # A training world of its own per SafeTail: the same requests, read afresh.
            train_world = ContentionWorld(replace(test_config, phase="train", n_requests=variant.train_requests),
                                          inputs, scenario)
            safetail = _safetail_policy(train_world, variant, config.base.seed)
            trained = run_policy(train_world, safetail, target=config.target)
            log(f"{label} {value:g}: {variant.name} trained on {variant.train_requests} requests "
                f"in {trained.wall_s:.1f} s")
            safetail.training = False
            policies.append((safetail, variant.train_requests))
        for name in config.methods:
            policies.append((make_baseline(name, test_world.n_servers, method_rng(config.base.seed, name),
                                           test_world.settings.baseline_reading), 0))
        for method in config.user_methods:
            policies.append(_user_policy(config, value, method, test_config, test_world, log))
        for policy, train_requests in policies:
            run = run_policy(test_world, policy, target=config.target)
            if on_test_run is not None:
                on_test_run(value, run)
            row = {**config.point_columns(value, test_world), **summarise(run), "train_requests": train_requests}
            rows.append(row)
            log(f"{label} {value:g}: {policy.name:<11} {_row_line(row)}  ({run.wall_s:.1f} s)")
    return pd.DataFrame(rows, columns=list(config.columns))
