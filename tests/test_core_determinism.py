"""Same seed, byte-identical results; seeds actually drive the random parts."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from yafs_examples.scenarios import FixedPlacement, MulticastAll, UserPopulation, line_topology

from yafs_safetail.yafs.application import Application, Message, fractional_selectivity
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import exponential_distribution, uniformDistribution

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


def forwarded(tmp_path, seed, threshold=0.5):
    topology = line_topology([(0, 1, 1, 1), (1, 2, 1, 1)], {0: 1.0, 1: 10.0, 2: 10.0})
    sim = Sim(topology, default_results_path=str(tmp_path / f"f{seed}"), seed=seed)
    placement = FixedPlacement("Svc", [1])
    sim.deploy_app(filtered_app(threshold), placement, UserPopulation(0, "Req", 10), MulticastAll())
    sim.deploy_module("filter", "Out", sim.apps["filter"].services["Out"], [2])
    sim.run(2000)
    rows = (tmp_path / f"f{seed}.csv").read_text().splitlines()
    return [r for r in rows if ",Fwd," in r]


def test_fractional_selectivity_draws_from_the_sim_generator(tmp_path):
    first, again, other = forwarded(tmp_path, 1), forwarded(tmp_path, 1), forwarded(tmp_path, 2)
    assert first == again and first != other
    assert 60 < len(first) < 140  # about half of 199 requests forwarded
    assert len(forwarded(tmp_path, 5, threshold=1.0)) == 199


def test_fractional_selectivity_without_generator_refuses_to_use_global_state():
    assert fractional_selectivity(1.0) is True
    with pytest.raises(ValueError, match="rng"):
        fractional_selectivity(0.5)


def test_distributions_are_seeded():
    a = exponential_distribution(5.0, seed=7)
    b = exponential_distribution(5.0, seed=7)
    draws = [a.next() for _ in range(50)]
    assert draws == [b.next() for _ in range(50)]
    assert all(isinstance(v, int) and v >= 1 for v in draws)
    u = uniformDistribution(2, 4, seed=1)
    assert {u.next() for _ in range(200)} == {2, 3, 4}
