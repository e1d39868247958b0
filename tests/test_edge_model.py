"""The edge model in the core: every copy obeys Eq. 1, refusals, topology edits."""

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, trace_inputs
from yafs_safetail.methods import Oracle, RandX
from yafs_safetail.sim.hooks import EdgeModel, edge_application
from yafs_safetail.sim.placement import EdgePlacement
from yafs_safetail.sim.population import EdgePopulation
from yafs_safetail.sim.selection import PolicySelection
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.topology import Topology

ROOT = Path(__file__).resolve().parents[1]


def inputs_for(traces, uc):
    rough = trace_inputs(traces, uc, lambda g, k: np.zeros(len(k)))
    median = rough.median_compute_by_k_s
    # Γ enters so that compute time differs per request (like the real model would).
    return trace_inputs(
        traces, uc,
        lambda g, k: median[np.asarray(k) - 1] * (1 + (g[:, 0] / 1e7 if g.shape[1] else 0)),
    )


def run(world, policy, n_steps, listeners=(), selection_class=PolicySelection):
    model = EdgeModel(world)
    scenario = world.scenario
    topology = Topology()
    topology.load(scenario.topology.data)
    sim = Sim(topology, link_delay=model, service_model=model, write_results=False)
    selection = selection_class(model, policy)
    population = EdgePopulation(scenario.user_node)
    sim.deploy_app(edge_application(scenario.app_name, scenario.module_name),
                   EdgePlacement(scenario.placement), population, selection)
    sim.request_listeners.extend(listeners)
    sim.run(until=population.until_s(n_steps))
    return model, selection


def scenario_from(topo, place):
    return load_scenario(topo, place)


def test_every_copy_latency_equals_its_eq1_decomposition(traces):
    uc = get_use_case(2)
    scenario = load_scenario(ROOT / "topologies/paper_5servers.json", ROOT / "placements/paper_5servers.json")
    world = build_world(scenario, uc, inputs_for(traces, uc), 150, seed=7, phase="test")
    checked = []

    class Checking(PolicySelection):
        def on_request_complete(self, sim, outcome):
            # Before the selection forgets the request's copies, compare each answered copy.
            record_step = self.edge_model.begin_request(outcome.request_id)
            for copy_outcome in outcome.copies:
                server = self.edge_model.server_index(copy_outcome.dst_node)
                parts = self.edge_model.copy_breakdown(outcome.request_id, server)
                if copy_outcome.status == "answered":
                    latency = copy_outcome.time_end - outcome.time_emit
                    assert latency == pytest.approx(parts.total_s, rel=1e-9, abs=1e-12)
                    table = world.copy_latency(record_step, server, int(world.background_users[record_step, server]))
                    assert parts.total_s == pytest.approx(table.total_s, rel=1e-9)
                    checked.append(server)
                else:
                    assert copy_outcome.status == "refused" and parts is None
            super().on_request_complete(sim, outcome)

    model, selection = run(world, Oracle(5, np.random.default_rng(0)), 150, selection_class=Checking)
    assert len(selection.records) == 150
    assert len(checked) > 300
    for record in selection.records:
        if not record.fallback:
            parts_sum = record.upload_s + record.propagation_s + record.download_s + record.compute_s
            assert record.latency_s == pytest.approx(parts_sum, rel=1e-9)
    np.testing.assert_allclose(
        [r.latency_s for r in selection.records],
        np.where(np.isinf(world.copy_latency_table_s().min(axis=1)), world.fallback_latency_s,
                 world.copy_latency_table_s().min(axis=1)),
    )


def test_server_at_max_load_refuses_and_all_refused_falls_back(traces):
    uc = get_use_case(1)
    scenario = load_scenario(ROOT / "topologies/3servers.json", ROOT / "placements/3servers.json")
    world = build_world(scenario, uc, inputs_for(traces, uc), 1000, seed=11, phase="test", episode_steps=50)
    model, selection = run(world, Oracle(world.n_servers, np.random.default_rng(0)), 1000)
    full = world.background_users >= 4
    for record in selection.records:
        assert record.refused == int(full[record.step].sum())
        assert record.fallback == bool(full[record.step].all())
        if record.fallback:
            assert record.latency_s == uc.fallback_latency_s and record.winner == -1
            assert np.isnan(record.compute_s)
    assert any(r.refused for r in selection.records)
    # Own copies are released: nothing is left running after the run.
    assert not any(model._own_running)


def test_compute_uses_k_equal_active_users_plus_one(traces):
    uc = get_use_case(1)
    scenario = load_scenario(ROOT / "topologies/paper_5servers.json", ROOT / "placements/paper_5servers.json")
    world = build_world(scenario, uc, inputs_for(traces, uc), 100, seed=3, phase="test")
    model, selection = run(world, Oracle(world.n_servers, np.random.default_rng(0)), 100)
    for record in selection.records:
        if record.fallback:
            continue
        b = world.background_users[record.step, record.winner]
        assert record.compute_s == world.compute_by_processes_s[record.step, record.winner, b]


def _edited(mutate):
    topo = json.loads((ROOT / "topologies/paper_5servers.json").read_text())
    place = json.loads((ROOT / "placements/paper_5servers.json").read_text())
    topo, place = copy.deepcopy(topo), copy.deepcopy(place)
    mutate(topo, place)
    return load_scenario(topo, place, known_conditions=range(1, 6), n_load_devices=10)


def test_editing_the_topology_changes_the_simulation(traces):
    uc = get_use_case(1)
    inputs = inputs_for(traces, uc)

    def latencies(scenario):
        world = build_world(scenario, uc, inputs, 200, seed=5, phase="test")
        return np.array([r.latency_s for r in run(world, Oracle(world.n_servers, np.random.default_rng(0)), 200)[1].records])

    base = latencies(_edited(lambda t, p: None))

    def all_far(t, p):
        for link in t["link"][1:]:
            link["condition"] = 5

    far = latencies(_edited(all_far))
    assert np.median(far) > np.median(base) + 0.3

    def drop_two(t, p):
        t["entity"] = t["entity"][:-2]
        t["link"] = t["link"][:-2]
        p["initialAllocation"] = p["initialAllocation"][:-2]

    fewer = latencies(_edited(drop_two))
    assert fewer.shape == base.shape and np.all(fewer >= base - 1e-12) and np.any(fewer > base)


def test_replies_route_back_to_the_user_and_population_runs_n_steps(traces):
    uc = get_use_case(3)
    scenario = load_scenario(ROOT / "topologies/7servers.json", ROOT / "placements/7servers.json")
    world = build_world(scenario, uc, inputs_for(traces, uc), 60, seed=1, phase="test")
    rng = np.random.default_rng(0)
    model, selection = run(world, RandX(7, rng, 3), 60)
    assert [r.step for r in selection.records] == list(range(60))
    assert all(r.time_emit_s == pytest.approx(60.0 * r.step) for r in selection.records)
    assert all(len(r.servers) == 3 and r.n_servers == 7 for r in selection.records)
    assert model.requests_seen == 60


def test_example_script_runs(tmp_path):
    import subprocess
    import sys

    if not (ROOT / "traces" / "models" / "compute_uc1.npz").is_file():
        pytest.skip("compute models not generated yet (python traces/generate.py)")
    result = subprocess.run(
        [sys.executable, str(ROOT / "examples/paper_scenario/main.py"), "--steps", "60", "--method", "MinLoad-2"],
        capture_output=True, text=True, timeout=120, check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "median" in result.stdout and "p99" in result.stdout
