"""The paper's baselines, and common random numbers across methods."""

from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world
from yafs_safetail.methods import (
    MinLoadX,
    MinPropX,
    Oracle,
    Policy,
    PolicyError,
    RandX,
    make_baseline,
)
from yafs_safetail.sim.runner import simulate

ROOT = Path(__file__).resolve().parents[1]
N_STEPS = 500


@pytest.fixture(scope="module")
def world(uc1_median_inputs, paper_scenario):
    return build_world(paper_scenario, get_use_case(1), uc1_median_inputs, N_STEPS, seed=21,
                       phase="test", episode_steps=64)


def run(world, name, seed=0, n_steps=N_STEPS):
    return simulate(world, make_baseline(name, world.n_servers, np.random.default_rng(seed)),
                    n_requests=n_steps)


BASELINES = ["Rand-1", "Rand-2", "Rand-3", "MinLoad-1", "MinLoad-2", "MinLoad-3", "MinProp-1", "MinProp-2", "MinProp-3"]


def test_oracle_is_a_per_request_lower_bound(world):
    oracle = np.array([r.latency_s for r in run(world, "Oracle")])
    assert oracle.shape == (N_STEPS,)
    for name in BASELINES:
        latency = np.array([r.latency_s for r in run(world, name, seed=4)])
        assert np.all(oracle <= latency + 1e-12), name
    # The bound is not trivial: single-server baselines are often slower.
    rand1 = np.array([r.latency_s for r in run(world, "Rand-1", seed=4)])
    assert np.mean(oracle < rand1 - 1e-9) > 0.3


def test_a_copy_latency_does_not_depend_on_the_subset(world):
    rand = run(world, "Rand-2", seed=1)
    table = world.copy_latency_table_s()
    for record in rand:
        chosen = table[record.step, list(record.servers)]
        expected = world.fallback_latency_s if np.all(np.isinf(chosen)) else chosen.min()
        assert record.latency_s == pytest.approx(expected, rel=1e-9)


def test_same_seed_same_choices_different_seed_different(world):
    a = [r.servers for r in run(world, "Rand-2", seed=9, n_steps=100)]
    b = [r.servers for r in run(world, "Rand-2", seed=9, n_steps=100)]
    c = [r.servers for r in run(world, "Rand-2", seed=10, n_steps=100)]
    assert a == b and a != c
    assert all(len(s) == 2 for s in a)


def test_minload_picks_the_least_loaded_servers(world):
    records = run(world, "MinLoad-2", seed=3)
    for record in records:
        load = world.background_users[record.step]
        chosen = load[list(record.servers)]
        others = np.delete(load, list(record.servers))
        assert chosen.max() <= others.min()
    # Ties are broken at random, not always by index.
    tied = [r for r in records if np.sum(world.background_users[r.step] == world.background_users[r.step].min()) >= 3]
    assert len(tied) > 10
    assert len({r.servers for r in tied}) > 1


def test_minprop_picks_the_nearest_servers(world):
    records = run(world, "MinProp-3", n_steps=20)
    assert {r.servers for r in records} == {(0, 1, 2)}  # conditions 1, 2, 3 of the paper topology


def test_records_carry_the_metrics(world):
    records = run(world, "Oracle", n_steps=50)
    record = records[10]
    assert record.method == "Oracle" and record.access_rate == 1.0 and record.n_selected == 5
    assert record.target_s == world.target_s[10]
    assert record.deviation_s == pytest.approx(record.target_s - record.latency_s)


def test_bad_baseline_parameters():
    rng = np.random.default_rng(0)
    with pytest.raises(PolicyError, match=r"x must be an integer in 1\.\.5"):
        RandX(5, rng, 6)
    with pytest.raises(PolicyError, match="x must be"):
        MinLoadX(5, rng, 0)
    with pytest.raises(PolicyError, match="unknown baseline 'Best-2'"):
        make_baseline("Best-2", 5, rng)
    with pytest.raises(PolicyError, match="unknown baseline 'Oracle-2'"):
        make_baseline("Oracle-2", 5, rng)
    assert isinstance(make_baseline("MinProp-4", 5, rng), MinPropX)
    assert make_baseline("Oracle", 5, rng).name == "Oracle"
    assert isinstance(Oracle(5, rng), Policy)


@pytest.mark.parametrize("bad", [(0, 0), (), (5,), (-1,), ("a",)])
def test_a_policy_returning_a_bad_subset_is_caught(world, bad):
    class Broken(Policy):
        observes = False

        def choose(self, observation):
            return bad

    with pytest.raises(PolicyError, match="Broken: (invalid subset|choose\\(\\) must return)"):
        simulate(world, Broken(world.n_servers, np.random.default_rng(0)))
