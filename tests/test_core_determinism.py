"""Same seed, byte-identical results; seeds actually drive the random parts."""

from __future__ import annotations

import importlib.util
import random
import warnings
from pathlib import Path

import numpy as np
import pytest
from yafs_examples.scenarios import FixedPlacement, MulticastAll, UserPopulation, line_topology

from yafs_safetail.yafs.application import Application, Message, fractional_selectivity
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import (
    exponential_distribution,
    exponentialDistribution,
    exponentialDistributionStartPoint,
    uniformDistribution,
)

BASIC = Path(__file__).resolve().parents[1] / "examples" / "yafs_basic" / "main.py"


def load_basic():
    spec = importlib.util.spec_from_file_location("yafs_basic_main", BASIC)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_same_seed_gives_byte_identical_csvs(tmp_path):
    basic = load_basic()
    outputs = []
    for run, seed in enumerate([3, 3, 4]):
        folder = tmp_path / f"run{run}"
        folder.mkdir()
        basic.main(20, 2, str(folder) + "/", seed=seed)
        outputs.append(((folder / "sim_trace.csv").read_bytes(), (folder / "sim_trace_link.csv").read_bytes()))
    assert outputs[0] == outputs[1]
    assert outputs[0] != outputs[2]
    assert outputs[0][0].count(b"\n") > 50


def filtered_app(threshold):
    app = Application("filter")
    app.set_modules([{"Svc": {"RAM": 1, "Type": Application.TYPE_MODULE}},
                     {"Out": {"RAM": 1, "Type": Application.TYPE_MODULE}}])
    req = Message("Req", "None", "Svc", instructions=1, bytes=10)
    fwd = Message("Fwd", "Svc", "Out", instructions=1, bytes=10)
    app.add_source_messages(req)
    app.add_service_module("Svc", req, fwd, fractional_selectivity, threshold=threshold)
    app.add_service_module("Out", fwd)
    return app


def forwarded(tmp_path, label, threshold=0.5, **sim_args):
    topology = line_topology([(0, 1, 1, 1), (1, 2, 1, 1)], {0: 1.0, 1: 10.0, 2: 10.0})
    sim = Sim(topology, default_results_path=str(tmp_path / f"f{label}"), **sim_args)
    placement = FixedPlacement("Svc", [1])
    sim.deploy_app(filtered_app(threshold), placement, UserPopulation(0, "Req", 10), MulticastAll())
    sim.deploy_module("filter", "Out", sim.apps["filter"].services["Out"], [2])
    sim.run(2000)
    rows = (tmp_path / f"f{label}.csv").read_text().splitlines()
    return [r for r in rows if ",Fwd," in r]


@pytest.fixture
def global_random_state():
    """Tests that seed Python's global generator put its state back afterwards."""
    state = random.getstate()
    yield
    random.setstate(state)


def test_yafs3_filter_draws_from_py_random_when_given(tmp_path):
    first = forwarded(tmp_path, "a", py_random=random.Random(1))
    again = forwarded(tmp_path, "b", py_random=random.Random(1))
    other = forwarded(tmp_path, "c", py_random=random.Random(2))
    assert first == again and first != other
    assert 60 < len(first) < 140  # about half of 199 requests forwarded
    assert len(forwarded(tmp_path, "d", threshold=1.0, py_random=random.Random(5))) == 199


def test_yafs3_filter_draws_from_the_global_random_by_default(tmp_path, global_random_state):
    # YAFS3 draws from Python's global generator: seeding it reproduces a seeded py_random.
    random.seed(1)
    from_global = forwarded(tmp_path, "g")
    assert from_global == forwarded(tmp_path, "p", py_random=random.Random(1))
    random.seed(2)
    assert forwarded(tmp_path, "h") != from_global


def test_direct_filter_draws_from_the_sim_generator(tmp_path):
    first = forwarded(tmp_path, "a", seed=1, engine="direct")
    again = forwarded(tmp_path, "b", seed=1, engine="direct")
    assert first == again and first != forwarded(tmp_path, "c", seed=2, engine="direct")
    assert 60 < len(first) < 140


def test_fractional_selectivity_draws_once_per_call_even_at_threshold_one(global_random_state):
    thresholds = (1.0, 0.5, 0.0, 0.5, 0.9)
    rng, reference = random.Random(3), random.Random(3)
    expected = [reference.random() <= t for t in thresholds]
    assert [fractional_selectivity(t, rng=rng) for t in thresholds] == expected
    assert rng.getstate() == reference.getstate()
    random.seed(3)
    assert [fractional_selectivity(t) for t in thresholds] == expected
    generator = np.random.default_rng(4)
    draws = np.random.default_rng(4).random(len(thresholds))
    assert [fractional_selectivity(t, rng=generator) for t in thresholds] == [
        bool(d <= t) for d, t in zip(draws, thresholds, strict=True)]


def test_global_draws_of_yafs_distributions(global_random_state):
    random.seed(11)
    reference = random.Random(11)
    uniform = uniformDistribution(0, 9)
    assert [uniform.next() for _ in range(30)] == [reference.randint(0, 9) for _ in range(30)]
    numpy_state = np.random.get_state()
    try:
        np.random.seed(5)
        start_point = exponentialDistributionStartPoint(500, 100.0)
        values = [start_point.next() for _ in range(20)]
        legacy = np.random.RandomState(5)
        assert values == [500] + [int(legacy.exponential(100.0, size=1)[0]) for _ in range(19)]
        seeded = exponentialDistributionStartPoint(500, 100.0, rng=np.random.RandomState(5))
        assert [seeded.next() for _ in range(20)] == values
    finally:
        np.random.set_state(numpy_state)


def test_exponential_distribution_keeps_yafs_stream_and_old_name_warns():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = exponentialDistribution(name="Exp", lambd=50, seed=9)
    assert any(issubclass(w.category, FutureWarning) for w in caught)
    new = exponential_distribution(50, seed=9)
    legacy = np.random.RandomState(9)
    expected = [max(int(legacy.exponential(50, size=1)[0]), 1) for _ in range(40)]
    assert [old.next() for _ in range(40)] == expected == [new.next() for _ in range(40)]


def test_distributions_are_seeded():
    a = exponential_distribution(5.0, seed=7)
    b = exponential_distribution(5.0, seed=7)
    draws = [a.next() for _ in range(50)]
    assert draws == [b.next() for _ in range(50)]
    assert all(isinstance(v, int) and v >= 1 for v in draws)
    u = uniformDistribution(2, 4, seed=1)
    assert {u.next() for _ in range(200)} == {2, 3, 4}


def test_exponential_distributions_share_a_seeds_stream_and_continue_past_it(monkeypatch):
    from yafs_safetail.yafs import distribution

    monkeypatch.setattr(distribution, "_SHARED_DRAWS", 64)
    monkeypatch.setattr(distribution, "_STREAMS", {})
    expected = np.random.RandomState(11).exponential(3.0, size=500).tolist()
    first = exponential_distribution(3.0, seed=11, integer=False)
    assert [first.next() for _ in range(100)] == expected[:100]  # past the shared part
    second = exponential_distribution(3.0, seed=11, integer=False)  # starts at the beginning
    assert [second.next() for _ in range(30)] == expected[:30]
    assert [first.next() for _ in range(400)] == expected[100:]
    assert [second.next() for _ in range(470)] == expected[30:]
    assert len(distribution._STREAMS[11].values) <= 64 + 512
    other = exponential_distribution(3.0, seed=np.int64(11), integer=False)  # not shared
    assert [other.next() for _ in range(10)] == expected[:10]
