"""A topology's link BW (YAFS's megabytes per second) and PR rescale the traces: editing them changes the simulation."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, link_scales
from yafs_safetail.methods import Oracle, RandX
from yafs_safetail.sim.runner import simulate

ROOT = Path(__file__).resolve().parents[1]
TOPOLOGY = ROOT / "topologies" / "paper_5servers.json"
PLACEMENT = ROOT / "placements" / "paper_5servers.json"
STEPS = 300


@pytest.fixture(scope="module")
def inputs(uc1_median_inputs):
    return uc1_median_inputs


def edited(tmp_path: Path, edit) -> Path:
    data = json.loads(TOPOLOGY.read_text())
    edit(data)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(data))
    return path


def server_link(data: dict, node: int) -> dict:
    return next(link for link in data["link"] if node in (link["s"], link["d"]) and "condition" in link)


def world_of(topology: Path, inputs) -> object:
    scenario = load_scenario(topology, PLACEMENT)
    return build_world(scenario, get_use_case(1), inputs, STEPS, seed=4, phase="test")


def test_shipped_topology_uses_the_traces_as_measured():
    scales = link_scales(load_scenario(TOPOLOGY, PLACEMENT))
    assert np.all(scales.server_bandwidth == 1.0) and scales.user_bandwidth == 1.0
    assert np.all(scales.server_extra_propagation_s == 0.0)


def test_server_link_bw_scales_that_servers_bandwidth_only(tmp_path, inputs):
    base = world_of(TOPOLOGY, inputs)
    doubled = world_of(edited(tmp_path, lambda d: server_link(d, 2).update(BW=5)), inputs)
    np.testing.assert_allclose(doubled.server_downlink_by_level_bps[:, 0],
                               2 * base.server_downlink_by_level_bps[:, 0])
    np.testing.assert_array_equal(doubled.server_uplink_by_level_bps[:, 1:],
                                  base.server_uplink_by_level_bps[:, 1:])
    # Faster server link: its transfers never get slower, and some get faster.
    assert np.all(doubled.input_transfer_by_level_s[:, 0] <= base.input_transfer_by_level_s[:, 0])
    assert np.any(doubled.input_transfer_by_level_s[:, 0] < base.input_transfer_by_level_s[:, 0])


def test_link_pr_adds_wired_propagation_to_that_server_only(tmp_path, inputs):
    base = world_of(TOPOLOGY, inputs)
    moved = world_of(edited(tmp_path, lambda d: server_link(d, 2).update(PR=0.25)), inputs)
    np.testing.assert_allclose(moved.rtt_s[:, 0], base.rtt_s[:, 0] + 0.25)
    assert moved.median_propagation_s[0] == pytest.approx(base.median_propagation_s[0] + 0.25)
    np.testing.assert_array_equal(moved.rtt_s[:, 1:], base.rtt_s[:, 1:])


def test_user_link_pr_adds_to_every_server(tmp_path, inputs):
    base = world_of(TOPOLOGY, inputs)
    user_link = lambda d: next(link for link in d["link"] if "condition" not in link)  # noqa: E731
    moved = world_of(edited(tmp_path, lambda d: user_link(d).update(PR=0.1)), inputs)
    np.testing.assert_allclose(moved.rtt_s, base.rtt_s + 0.1)
    assert np.all(moved.target_s > base.target_s)


def test_user_link_bw_scales_the_users_bandwidth_and_the_target(tmp_path, inputs):
    base = world_of(TOPOLOGY, inputs)
    user_link = lambda d: next(link for link in d["link"] if "condition" not in link)  # noqa: E731
    slow = world_of(edited(tmp_path, lambda d: user_link(d).update(BW=0.625)), inputs)
    np.testing.assert_allclose(slow.user_uplink_bps, base.user_uplink_bps / 4)
    assert np.all(slow.target_s > base.target_s)


def test_a_very_slow_link_raises_the_fallback_and_oracle_stays_a_lower_bound(tmp_path, inputs):
    base = world_of(TOPOLOGY, inputs)
    crawling = world_of(edited(tmp_path, lambda d: server_link(d, 6).update(BW=0.025)), inputs)
    assert base.fallback_latency_s == get_use_case(1).fallback_latency_s
    assert crawling.fallback_latency_s > base.fallback_latency_s
    oracle = simulate(crawling, Oracle(crawling.n_servers, np.random.default_rng(0)))
    rand = simulate(crawling, RandX(crawling.n_servers, np.random.default_rng(0), 1))
    assert max(r.latency_s for r in rand) > 30  # the crawling link is really used
    for o, r in zip(oracle, rand, strict=True):
        assert o.step == r.step and o.latency_s <= r.latency_s + 1e-12


def test_bw_is_read_in_yafs_units_once_at_the_boundary():
    scenario = load_scenario(TOPOLOGY, PLACEMENT)
    # The shipped files' BW 2.5 (MB/s, YAFS's unit) is the traces' uncontended 20 Mbit/s.
    assert scenario.user_link_bandwidth_bps == 20e6
    assert scenario.server_link_bandwidth_bps == (20e6,) * 5
