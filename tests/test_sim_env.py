"""The Gymnasium environment: registration, Gymnasium's own checker, seeding, episodes, and the
SafeTail learner trained through it matching ``run_experiment`` file for file."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import yafs_safetail
from yafs_safetail import results
from yafs_safetail.methods.registry import SAFETAIL, method_rng
from yafs_safetail.methods.safetail.learner import SafeTailLearner
from yafs_safetail.methods.safetail.policy import SafeTailPolicy
from yafs_safetail.methods.safetail.spaces import (
    StateScales,
    action_of,
    n_actions,
    state_dim,
    subset_of,
)
from yafs_safetail.record import records_frame
from yafs_safetail.runs.experiment import YAFS_DIR, ExperimentConfig, run_experiment
from yafs_safetail.sim.env import SafeTailEnv
from yafs_safetail.worlds.recipe import make_world

TINY = 0.02  # UC1: 200 training steps (within one α_s = 256 episode), 80 test steps


def make(**options) -> gymnasium.Env:
    return gymnasium.make(yafs_safetail.ENV_ID, **{"use_case": 1, "steps_scale": TINY, **options})


def checked(env: gymnasium.Env) -> None:
    """Gymnasium's checker, with its notes on unbounded Box limits (bandwidths and bytes have
    no upper bound) silenced and every other warning kept as an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=r".*Box observation space (maximum|minimum) value is")
        check_env(env.unwrapped, skip_render_check=True)


def test_importing_the_package_registers_the_environment():
    spec = gymnasium.spec(yafs_safetail.ENV_ID)
    assert spec.entry_point == "yafs_safetail.sim.env:SafeTailEnv"
    env = make()
    assert isinstance(env.unwrapped, SafeTailEnv)
    assert env.action_space == gymnasium.spaces.Discrete(n_actions(5))


@pytest.mark.parametrize(("use_case", "observation"), [(1, "dict"), (2, "dict"), (3, "vector")])
def test_gymnasiums_checker_passes(use_case, observation):
    checked(make(use_case=use_case, observation=observation))


def test_observation_fields_match_the_state_the_selection_sees():
    env = make(use_case=2)
    observation, info = env.reset(seed=1)
    omega = info["observation"]
    assert set(observation) == {"server_uplink_bps", "server_downlink_bps", "server_memory_util",
                                "server_cpu_util", "server_active_users", "server_median_propagation_s",
                                "server_max_load", "input_bytes", "est_output_bytes", "gamma",
                                "user_location", "user_uplink_bps", "user_downlink_bps", "server_condition"}
    assert observation["server_condition"].tolist() == [1, 2, 3, 4, 5]  # the paper topology's links
    for name, value in observation.items():
        np.testing.assert_allclose(value, np.atleast_1d(getattr(omega, name)).astype(np.float32))
    assert "gamma" not in make(use_case=1).reset(seed=1)[0]  # UC1 has no Γ


def test_a_step_is_one_request_with_the_eq5_reward():
    env = make()
    _, info = env.reset(seed=2)
    _, reward, terminated, truncated, info = env.step(action_of((0, 3), 5))
    record = info["record"]
    assert record.step == 0 and record.servers == (0, 3) and not terminated and not truncated
    assert reward == record.reward <= 0.0
    assert info["observation"].step == 1


def test_same_seed_same_trajectory_and_another_seed_differs():
    def trajectory(seed: int) -> list[tuple[float, float]]:
        env = make()
        env.reset(seed=seed)
        actions = np.random.default_rng(0).integers(0, n_actions(5), 50)
        return [(r, i["record"].latency_s) for r, i in
                (env.step(int(a))[1::3] for a in actions)]

    assert trajectory(7) == trajectory(7)
    assert trajectory(7) != trajectory(8)


def test_episodes_are_alpha_s_requests_and_a_used_up_world_is_replaced():
    env = make(phase="test", steps_scale=0.01)  # 40 test steps, α_s = 256 > 40: one episode
    env.reset(seed=3)
    steps = 0
    truncated = False
    while not truncated:
        *_, truncated, info = env.step(0)
        steps += 1
    assert steps == env.unwrapped.n_steps == 40
    with pytest.raises(RuntimeError, match="call reset"):
        env.unwrapped.step(0)
    first_world = env.unwrapped.world
    env.reset()  # the world is used up: a fresh one from the environment's generator
    assert env.unwrapped.world is not first_world
    assert env.step(0)[4]["record"].step == 0


def test_bad_actions_and_arguments_are_one_line_errors():
    env = make()
    env.reset(seed=0)
    for bad in (-1, n_actions(5), 2.5):
        with pytest.raises(ValueError, match="action: expected an integer"):
            env.unwrapped.step(bad)
    for options, fragment in [({"phase": "warmup"}, "phase"), ({"observation": "image"}, "observation"),
                              ({"steps_scale": 0}, "steps_scale"), ({"use_case": 4}, "4"),
                              ({"preset": "fancy"}, "fancy")]:
        with pytest.raises(ValueError, match=fragment) as caught:
            SafeTailEnv(**{"use_case": 1, **options})
        assert "\n" not in str(caught.value)


def test_the_environment_takes_the_experiments_world_options():
    """The env's world is the experiment's recipe: the same overrides give the same draws."""
    options = {"target_latency_s": 1.5, "load_peak_users": 2.0, "target_compute": "request"}
    env = make(phase="test", **options)
    env.reset(seed=3)
    world = env.unwrapped.world
    assert np.all(world.target_s == 1.5)
    assert world.settings.load_peak_users == 2.0 and world.settings.target_compute == "request"
    expected = make_world(ExperimentConfig(use_case=1, steps_scale=TINY, seed=3, **options), "test")
    for name in ("target_s", "background_users", "rtt_s", "input_bytes", "target_compute_s"):
        np.testing.assert_array_equal(getattr(world, name), getattr(expected, name))
    plain = make(phase="test")
    plain.reset(seed=3)
    assert not np.array_equal(plain.unwrapped.world.background_users, world.background_users)
    for bad, fragment in [({"target_latency_s": 0}, "target_latency_s"),
                          ({"load_peak_users": -1.0}, "load_peak_users"),
                          ({"target_compute": "mean"}, "target_compute")]:
        with pytest.raises(ValueError, match=f"^{fragment}: ") as caught:
            SafeTailEnv(use_case=1, **bad)
        assert "\n" not in str(caught.value)


def test_safetail_trained_through_the_environment_gives_the_experiments_files(tmp_path):
    """One simulation behind both: same seed, same records, same YAFS rows, same weights."""
    seed = 5
    run = run_experiment(ExperimentConfig(
        use_case=1, seed=seed, out_dir=tmp_path / "run", steps_scale=TINY, redundancy_levels=(1,),
        figures=False, write_yafs_csv=True, progress=False, workers=1, command="test"))

    env = make(method_name=SAFETAIL, results_path=tmp_path / "env" / f"{SAFETAIL}_train")
    config = env.unwrapped.learner_config
    scenario = env.unwrapped.scenario
    learner = SafeTailLearner(scenario.n_servers, state_dim(scenario.n_servers, 0, 2), config, seed,
                              metadata={"use_case": 1, "topology": str(ExperimentConfig().topology)})
    policy = SafeTailPolicy(scenario.n_servers, method_rng(seed, SAFETAIL), learner=learner,
                            scales=StateScales.for_use_case(1), training=True)
    _, info = env.reset(seed=seed)
    records = []
    for _ in range(env.unwrapped.n_steps):
        subset = policy.choose(info["observation"])
        _, _, _, truncated, info = env.step(action_of(subset, scenario.n_servers))
        assert info["record"].servers == subset_of(action_of(subset, 5), 5)
        records.append(policy.feedback(info["record"]))
        if truncated:
            _, info = env.reset()
    env.close()

    folder = tmp_path / "env"
    results.write_requests_csv(records_frame(records, "train", config.episode_steps), folder)
    ours = (folder / "requests.csv").read_text().splitlines()
    theirs = (run.out_dir / "requests.csv").read_text().splitlines()
    assert ours[0] == theirs[0]
    assert ours[1:] == [line for line in theirs if line.startswith(f"{SAFETAIL},train,")]
    assert len(ours) == 1 + 200
    learner.save(folder / "policy.keras")
    assert (folder / "policy.keras").read_bytes() == (run.out_dir / "policy.keras").read_bytes()
    for name in (f"{SAFETAIL}_train.csv", f"{SAFETAIL}_train_link.csv"):
        assert (folder / name).read_bytes() == (run.out_dir / YAFS_DIR / name).read_bytes()


def test_env_observations_are_what_the_policy_selection_builds():
    """ω^t read by the environment before issuing request t equals the one PolicySelection
    would build at issue time (the equivalence the identity test above relies on)."""
    env = make()
    _, info = env.reset(seed=9)
    unwrapped = env.unwrapped
    for action in np.random.default_rng(1).integers(0, n_actions(5), 30):
        expected = unwrapped.world.observation(info["observation"].step,
                                               unwrapped.world.background_users[info["observation"].step])
        assert info["observation"] == expected
        info = env.step(int(action))[4]


def test_vector_observation_is_safetails_encoded_state():
    env = make(use_case=3, observation="vector")
    observation, info = env.reset(seed=4)
    from yafs_safetail.methods.safetail.spaces import encode_state

    np.testing.assert_array_equal(observation, encode_state(info["observation"], StateScales.for_use_case(3)))
