"""The contention world as a Gymnasium environment: registration, Gymnasium's checker, seeding,
the reward's bookkeeping, episodes, its engine thread, and a fixed policy driven through it
giving exactly ``run_policy``'s run (the environment is the sweep's world)."""

from __future__ import annotations

import dataclasses
import gc
import inspect
import math
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import yafs_safetail
from yafs_safetail.contention.env import ENGINE_THREAD_NAME, ContentionEnv
from yafs_safetail.contention.run import run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.methods.registry import make_baseline
from yafs_safetail.methods.safetail.reward import LOAD_PRICE, latency_score, reward
from yafs_safetail.methods.safetail.spaces import action_of, n_actions, state_dim

#: A small busy world: 10 users at load 0.6, three blocks of requests.
SMALL = {"users": 10, "load": 0.6, "n_requests": 150, "block_requests": 50}


def make(**options) -> gymnasium.Env:
    return gymnasium.make(yafs_safetail.CONTENTION_ENV_ID, **{**SMALL, **options})


def engine_threads() -> int:
    return sum(thread.name == ENGINE_THREAD_NAME for thread in threading.enumerate())


def drive(env: gymnasium.Env, policy, seed: int) -> tuple[dict[int, float], dict]:
    """Every request of the run at ``seed`` dispatched by ``policy``: each request's latency
    from the records, and the last step's info."""
    _, info = env.reset(seed=seed)
    latency_s: dict[int, float] = {}
    truncated = False
    while not truncated:
        action = action_of(policy.choose(info["observation"]), env.unwrapped.n_servers)
        *_, truncated, info = env.step(action)
        latency_s.update((record.step, record.latency_s) for record in info["completed"])
    return latency_s, info


def test_importing_the_package_registers_the_environment():
    spec = gymnasium.spec(yafs_safetail.CONTENTION_ENV_ID)
    assert spec.entry_point == "yafs_safetail.contention.env:ContentionEnv"
    env = make()
    assert isinstance(env.unwrapped, ContentionEnv)
    assert env.action_space == gymnasium.spaces.Discrete(n_actions(5))
    env.close()


@pytest.mark.parametrize("imports", ["import yafs_safetail; import gymnasium",
                                     "import gymnasium; import yafs_safetail"])
def test_the_id_is_registered_whichever_is_imported_first(imports):
    code = f"{imports}; print(gymnasium.spec(yafs_safetail.CONTENTION_ENV_ID).entry_point)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout.strip() == "yafs_safetail.contention.env:ContentionEnv", done.stderr[-2000:]


def test_every_contention_setting_but_the_seed_is_a_keyword_with_its_default():
    parameters = inspect.signature(ContentionEnv).parameters
    for field in dataclasses.fields(ContentionConfig):
        if field.name == "seed":
            assert "seed" not in parameters  # reset(seed=...) gives it
            continue
        assert parameters[field.name].default == field.default, field.name


@pytest.mark.parametrize(("use_case", "observation"), [(1, "dict"), (2, "dict"), (3, "vector")])
def test_gymnasiums_checker_passes(use_case, observation):
    env = make(use_case=use_case, observation=observation)
    with warnings.catch_warnings():
        # Bandwidths and bytes have no upper bound: the checker's note on that is expected.
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=r".*Box observation space (maximum|minimum) value is")
        check_env(env.unwrapped, skip_render_check=True)
    if observation == "vector":
        n_gamma = len(env.unwrapped.use_case.gamma_columns)
        assert env.observation_space.shape == (state_dim(5, n_gamma, 2),)
    env.close()


@pytest.mark.parametrize(("method", "options"), [
    ("MinLoad-2", {}),
    ("Rand-2", {"queue": True}),  # draws from its generator at every choice
    ("Tied", {"dispatch": "tied", "user_conditions": "generated"}),
])
def test_a_fixed_policy_through_the_environment_is_run_policys_run(method, options):
    """The strongest check: driven request by request from outside, the same policy on the
    same settings and seed gives every request the latency ``run_policy`` gives it."""
    env = make(**options)
    latency_s, info = drive(env, make_baseline(method, 5, np.random.default_rng(9)), seed=4)
    config = ContentionConfig(seed=4, **SMALL, **{k: v for k, v in options.items() if k != "dispatch"})
    expected = run_policy(ContentionWorld(config), make_baseline(method, 5, np.random.default_rng(9)))
    assert sorted(latency_s) == list(range(SMALL["n_requests"]))
    np.testing.assert_array_equal([latency_s[j] for j in range(SMALL["n_requests"])], expected.result.latency_s)
    np.testing.assert_array_equal(info["run"].result.n_copies, expected.result.n_copies)
    row, expected_row = summarise(info["run"]), summarise(expected)
    assert {k: v for k, v in row.items() if k != "method"} == {k: v for k, v in expected_row.items() if k != "method"}
    assert engine_threads() == 0  # the run's thread ended with the run


def test_same_seed_same_trajectory_and_another_seed_differs():
    def trajectory(seed: int) -> list[tuple[tuple[float, ...], float]]:
        env = make(observation="vector")
        observation, _ = env.reset(seed=seed)
        actions = np.random.default_rng(0).integers(0, n_actions(5), SMALL["n_requests"])
        steps = [(tuple(observation.tolist()), 0.0)]
        for action in actions:
            observation, value, *_ = env.step(int(action))
            steps.append((tuple(observation.tolist()), value))
        env.close()
        return steps

    first = trajectory(7)
    assert first == trajectory(7)
    assert first != trajectory(8)
    assert any(value != 0.0 for _, value in first)  # the rewards are compared, not only zeros


def test_each_request_is_rewarded_once_when_it_completes():
    env = make()
    _, info = env.reset(seed=2)
    delta = env.unwrapped.delta
    rewarded: list[int] = []
    total = 0.0
    truncated = False
    while not truncated:
        request = info["request"]
        _, value, terminated, truncated, info = env.step(action_of((0, 1), 5))
        assert not terminated
        for record in info["completed"]:
            assert record.step <= request  # nothing completes before it is dispatched
            assert record.reward == reward(record.latency_s, record.target_s, 2, 5, delta)
        assert value == pytest.approx(sum(record.reward for record in info["completed"]))
        rewarded += [record.step for record in info["completed"]]
        total += value
    assert sorted(rewarded) == list(range(SMALL["n_requests"]))
    assert total < 0.0  # Eq. 5 with two copies: every met target costs a little
    env.close()


def test_the_latency_cost_reward_prices_the_copies_at_the_load_the_agent_saw():
    env = make(reward="latency-cost", dispatch="tied")
    _, info = env.reset(seed=3)
    seen_jobs: dict[int, int] = {}
    checked = 0
    for _ in range(SMALL["n_requests"]):
        seen_jobs[info["request"]] = int(info["observation"].server_active_users[[1, 2]].sum())
        *_, info = env.step(action_of((1, 2), 5))
        for record in info["completed"]:
            expected = latency_score(record.latency_s, record.target_s) - LOAD_PRICE * seen_jobs[record.step]
            assert math.isclose(record.reward, expected, rel_tol=0, abs_tol=1e-12)
            checked += 1
    assert checked == SMALL["n_requests"] and any(jobs > 0 for jobs in seen_jobs.values())
    env.close()


def test_episodes_split_a_run_and_a_used_up_run_is_replaced():
    env = make(episode_requests=60)
    env.reset(seed=5)
    lengths, first_requests = [], []
    for _ in range(3):
        _, info = env.reset() if lengths else (None, {"request": 0})
        first_requests.append(info["request"])
        steps, truncated = 0, False
        while not truncated:
            *_, truncated, info = env.step(0)
            steps += 1
        lengths.append(steps)
        with pytest.raises(RuntimeError, match="call reset"):
            env.unwrapped.step(0)
    assert lengths == [60, 60, 30] and first_requests == [0, 60, 120]  # the run's 150 requests
    assert "run" in info
    old_world = env.unwrapped.world
    _, info = env.reset()  # the run is used up: a fresh world from the environment's generator
    assert env.unwrapped.world is not old_world and info["request"] == 0
    env.close()


def test_reset_close_and_garbage_collection_leave_no_engine_thread():
    before = engine_threads()
    env = make()
    for seed in range(4):
        env.reset(seed=seed)
        env.step(0)
        assert engine_threads() == before + 1  # the previous run's thread is gone
    env.close()
    assert engine_threads() == before
    env.close()  # twice is harmless
    dropped = make()
    dropped.reset(seed=1)
    assert engine_threads() == before + 1
    del dropped
    gc.collect()
    for thread in threading.enumerate():
        if thread.name == ENGINE_THREAD_NAME:
            thread.join(timeout=10)
    assert engine_threads() == before


def test_an_exception_in_the_engine_surfaces_in_step(monkeypatch):
    env = make()
    original = ContentionWorld.block

    def broken(world, index):
        if index == 1:
            raise RuntimeError("block 1 cannot be drawn")
        return original(world, index)

    monkeypatch.setattr(ContentionWorld, "block", broken)
    env.reset(seed=1)  # the run's first block is drawn; the second, at request 50, fails
    with pytest.raises(RuntimeError, match="block 1 cannot be drawn"):
        for _ in range(SMALL["n_requests"]):
            env.step(0)
    assert engine_threads() == 0
    with pytest.raises(RuntimeError, match="call reset"):
        env.unwrapped.step(0)
    monkeypatch.setattr(ContentionWorld, "block", original)
    _, info = env.reset(seed=1)  # a failed run is replaced like any other
    assert info["request"] == 0
    env.close()


@pytest.mark.parametrize(("options", "field"), [
    ({"users": 0}, "users"), ({"load": -0.5}, "load"), ({"links": "wifi"}, "links"),
    ({"dispatch": "hedge"}, "dispatch"), ({"target": "mean"}, "target"), ({"reward": "speed"}, "reward"),
    ({"preset": "fancy"}, "preset"), ({"observation": "image"}, "observation"),
    ({"phase": "warmup"}, "phase"), ({"episode_requests": 0}, "episode_requests"),
])
def test_bad_arguments_are_one_line_errors_naming_the_field(options, field):
    with pytest.raises(ValueError, match=f"^{field}: ") as caught:
        ContentionEnv(**{**SMALL, **options})
    assert "\n" not in str(caught.value)


def test_bad_actions_are_one_line_errors():
    env = ContentionEnv(**SMALL)
    env.reset(seed=0)
    for bad in (-1, n_actions(5), 2.5):
        with pytest.raises(ValueError, match="^action: expected an integer"):
            env.step(bad)
    env.close()


def test_the_example_runs_an_outside_agent_beside_the_sweeps_methods():
    example = Path(__file__).resolve().parents[1] / "examples" / "contention_env.py"
    done = subprocess.run([sys.executable, str(example), "--requests", "300", "--users", "10"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    methods = [line.split()[0] for line in done.stdout.splitlines()[2:]]
    assert methods == ["most-free-pair", "random", "MinLoad-2", "Tied", "Oracle"]


@pytest.mark.slow
def test_safetail_ca_learning_through_the_environment_is_the_sweeps_run():
    """The sweep's contention-aware SafeTail, trained through the environment (its choices as
    actions, each completed record as its feedback), learns and dispatches exactly as
    ``run_policy`` trains it: feedback reaches it in the same order between its choices."""
    from yafs_safetail.methods.registry import SAFETAIL, method_rng
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.methods.safetail.spaces import StateScales

    settings = {"users": 20, "load": 0.5, "n_requests": 600, "block_requests": 200, "queue": True,
                "background": False, "phase": "train"}

    def safetail_ca(seed: int) -> SafeTailPolicy:
        config = dataclasses.replace(get_preset("tuned", 1, train_steps=600), objective="value")
        learner = SafeTailLearner(5, state_dim(5, 0, 2), config, seed, metadata={})
        return SafeTailPolicy(5, method_rng(seed, SAFETAIL), learner=learner, scales=StateScales.for_use_case(1),
                              training=True, reward_name="latency-cost", dispatch="tied")

    expected = run_policy(ContentionWorld(ContentionConfig(seed=2, **settings)), safetail_ca(2))
    policy = safetail_ca(2)
    env = make(dispatch="tied", reward="latency-cost", **settings)
    _, info = env.reset(seed=2)
    latency_s: dict[int, float] = {}
    truncated = False
    while not truncated:
        *_, truncated, info_after = env.step(action_of(policy.choose(info["observation"]), 5))
        for record in info_after["completed"]:
            assert policy.feedback(record).reward == pytest.approx(record.reward, abs=1e-12)
            latency_s[record.step] = record.latency_s
        info = info_after
    assert policy.learner.n_training_rounds > 0  # it learnt on the way
    np.testing.assert_array_equal([latency_s[j] for j in range(600)], expected.result.latency_s)
