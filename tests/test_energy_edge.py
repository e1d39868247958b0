"""Energy in the edge world: the copies' sum equals the servers' and the device's totals kept apart,
and SafeTail's priced reward is Eq. 5 when both prices are 0."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.energy import EnergyModel, ServerPowerModel
from yafs_safetail.edge.failures import FailureSettings
from yafs_safetail.edge.world import build_world
from yafs_safetail.methods.baselines import Oracle, RandX
from yafs_safetail.methods.policy import Policy
from yafs_safetail.methods.safetail import StateScales, reward, state_dim
from yafs_safetail.methods.safetail.reward import priced_reward
from yafs_safetail.sim import runner
from yafs_safetail.sim.hooks import EdgeModel
from yafs_safetail.sim.runner import deploy

ROOT = Path(__file__).resolve().parents[1]
#: Requests 1.5 s apart (UC1 copies take about 1-2 s): copies of consecutive requests overlap on the servers.
OVERLAPPING_STEP_S = 1.5


class _AccountedEdgeModel(EdgeModel):
    """The edge model with totals kept apart from its per-copy accounting (``request_fates``):
    per server, the integral over time of the copies holding a process (from the core's admit
    and release calls); the device's radio per transfer (from the user's hops). Also sums the
    copies' server energies per server as ``request_fates`` reads them."""

    def __init__(self, world) -> None:
        super().__init__(world)
        self.running = [0] * self.n_servers
        self.process_seconds = [0.0] * self.n_servers
        self.last_change_s = [0.0] * self.n_servers
        self.device_radio_energy_j = 0.0
        self.copies_server_energy_j = np.zeros(self.n_servers)

    def _processes_change(self, server: int, now_s: float, change: int) -> None:
        self.process_seconds[server] += self.running[server] * (now_s - self.last_change_s[server])
        self.last_change_s[server] = now_s
        self.running[server] += change

    def server_energy_totals_j(self, now_s: float) -> list[float]:
        """Each server's marginal energy of our copies up to ``now_s``, from the integral."""
        per_process_w = self.world.energy.server.per_process_w
        return [per_process_w * (seconds + running * (now_s - last_s))
                for seconds, running, last_s in zip(self.process_seconds, self.running,
                                                    self.last_change_s, strict=True)]

    def hop_delay_s(self, sim, message, src_node, dst_node):
        delay = super().hop_delay_s(sim, message, src_node, dst_node)
        if self.user_node in (src_node, dst_node):
            step = self.begin_request(message.id)
            state = self._copies[message.id][self.server_index(message.copy_dst_node)]
            radio = self.world.energy.radio
            self.device_radio_energy_j += (
                radio.upload_energy_j(float(self.world.input_bytes[step]), state.input_s)
                if src_node == self.user_node
                else radio.download_energy_j(float(self.world.output_bytes[step]), state.output_s))
        return delay

    def admit(self, sim, message, des, node, module):
        admitted = super().admit(sim, message, des, node, module)
        if admitted:
            self._processes_change(self.server_index(node), sim.env.now, +1)
        return admitted

    def release(self, sim, message, des, node, module):
        super().release(sim, message, des, node, module)
        self._processes_change(self.server_index(node), sim.env.now, -1)

    def request_fates(self, request_id):
        per_process_w = self.world.energy.server.per_process_w
        for state in self._copies.get(request_id, ()):
            if state is not None:
                self.copies_server_energy_j[state.server] += per_process_w * state.served_s
        return super().request_fates(request_id)


def _check_totals(world, policy: Policy, n_requests: int) -> tuple[int, int]:
    """Run ``policy`` request by request; at every moment with no copy running, the per-copy
    energies summed per server and for the device equal the totals kept apart
    (:class:`_AccountedEdgeModel`). Checked again once the last request's copies have all ended.
    Returns (moments checked before the end, requests whose copies overlapped an earlier
    request's)."""
    simulation = deploy(world, policy, OVERLAPPING_STEP_S)
    edge = simulation.edge
    assert isinstance(edge, _AccountedEdgeModel)

    def check() -> None:
        now_s = simulation.sim.env.now
        per_server = edge.copies_server_energy_j
        totals = edge.server_energy_totals_j(now_s)
        assert np.allclose(per_server, totals, rtol=0, atol=1e-9), (per_server, totals)
        records = simulation.records
        assert sum(r.server_energy_j for r in records) == pytest.approx(sum(totals), rel=0, abs=1e-9)
        assert sum(r.radio_energy_j for r in records) == pytest.approx(edge.device_radio_energy_j, rel=0, abs=1e-9)

    checked = 0
    for done in range(1, n_requests + 1):
        simulation.run_until_request(done)
        if simulation.quiescent:
            check()
            checked += 1
    # The user stops sending; every copy in flight ends; then the totals are complete.
    simulation.sim.des_process_running[simulation.population.source_des] = False
    simulation.sim.run(until=simulation.sim.env.now + 120.0)
    assert len(simulation.records) == n_requests and simulation.edge.copies_running == 0
    check()
    records = simulation.records
    overlapping = sum(1 for before, after in zip(records, records[1:], strict=False)
                      if before.latency_s > OVERLAPPING_STEP_S and set(before.servers) & set(after.servers))
    return checked, overlapping


@pytest.mark.parametrize("failures", [None, FailureSettings(mttf_s=6.0, mttr_s=3.0)])
def test_the_copies_energy_adds_up_to_each_servers_and_the_devices_totals(uc1, failures, monkeypatch):
    monkeypatch.setattr(runner, "EdgeModel", _AccountedEdgeModel)
    use_case, scenario, inputs = uc1
    energy = EnergyModel(server=ServerPowerModel(idle_w=12.5, max_w=80.0))
    world = build_world(scenario, use_case, inputs, 300, seed=4, phase="test", failures=failures,
                        energy=energy, step_interval_s=OVERLAPPING_STEP_S)
    for policy in (Oracle(world.n_servers, np.random.default_rng(0)),
                   RandX(world.n_servers, np.random.default_rng(0), 2)):
        checked, overlapping = _check_totals(world, policy, 250)
        assert checked >= 1 and overlapping > 0  # checked along the way, copies sharing a server
    if failures is not None:
        assert world.down_intervals is not None


def test_a_copys_energy_is_its_compute_times_the_marginal_power_plus_its_radio(uc1):
    use_case, scenario, inputs = uc1
    world = build_world(scenario, use_case, inputs, 40, seed=6, phase="test")
    simulation = deploy(world, RandX(world.n_servers, np.random.default_rng(3), 1))
    simulation.run_until_request(40)
    radio, server = world.energy.radio, world.energy.server
    for record in simulation.records:
        if record.fallback:  # refused: uploaded, never computed, nothing downloaded
            (i,) = record.servers
            level = min(int(world.background_users[record.step, i]), world.n_contention_levels - 1)
            upload_s = float(world.input_transfer_by_level_s[record.step, i, level])
            assert record.server_energy_j == 0.0
            assert record.radio_energy_j == radio.upload_energy_j(float(world.input_bytes[record.step]), upload_s)
            continue
        # Eq. 1's terms: each transfer is charged twice in the latency (upload and
        # download hops), once on the device's radio.
        upload_s = record.upload_s / 2
        download_s = record.download_s / 2
        expected = (radio.upload_energy_j(float(world.input_bytes[record.step]), upload_s)
                    + radio.download_energy_j(float(world.output_bytes[record.step]), download_s))
        assert record.radio_energy_j == pytest.approx(expected, rel=1e-12)
        assert record.server_energy_j == pytest.approx(server.per_process_w * record.compute_s, rel=1e-12)
        assert record.saved_energy_j == 0.0 and record.energy_j == record.server_energy_j + record.radio_energy_j


def test_the_priced_reward_is_eq5_itself_with_both_prices_zero():
    for base in (0.0, -0.25, -1.7e-3, -2.718281828459045):
        for energy_j in (0.0, 12.5, math.nan):
            for replied in (True, False):
                assert priced_reward(base, energy_j, replied, 0.0, 0.0) is base
    assert priced_reward(-0.5, 10.0, False, 0.01, 2.0) == -0.5 - 0.01 * 10.0 - 2.0
    assert priced_reward(-0.5, 10.0, True, 0.0, 2.0) == -0.5
    with pytest.raises(ValueError, match="energy_j must be finite"):
        priced_reward(0.0, math.nan, True, 0.1, 0.0)


def test_safetail_records_eq5_without_prices_and_the_priced_reward_with_them(uc1):
    """Greedy SafeTail (its choices never depend on rewards) on a world with failures."""
    import dataclasses

    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.sim.runner import simulate

    use_case, scenario, inputs = uc1
    world = build_world(scenario, use_case, inputs, 60, seed=8, phase="test",
                        failures=FailureSettings.for_unavailability(0.4))
    preset = get_preset("tuned", 1)
    outcomes = {}
    for prices in ((0.0, 0.0), (0.02, 1.5)):
        config = dataclasses.replace(preset, energy_price_per_j=prices[0], failure_penalty=prices[1])
        learner = SafeTailLearner(5, state_dim(5, 0, 2), config, seed=3)
        policy = SafeTailPolicy(5, np.random.default_rng(0), learner=learner,
                                scales=StateScales.for_use_case(1), training=False)
        outcomes[prices] = simulate(world, policy)
    plain, priced = outcomes[(0.0, 0.0)], outcomes[(0.02, 1.5)]
    assert [r.servers for r in plain] == [r.servers for r in priced]
    assert any(r.end_reason != "reply" for r in plain)
    for record, other in zip(plain, priced, strict=True):
        eq5 = reward(record.latency_s, record.target_s, record.n_selected, 5, preset.delta)
        assert record.reward == eq5
        penalty = 1.5 if record.end_reason != "reply" else 0.0
        assert other.reward == eq5 - 0.02 * record.energy_j - penalty
    assert "energy_price_per_j" not in preset.to_dict()  # files of unpriced learners unchanged
    assert dataclasses.replace(preset, failure_penalty=1.0).to_dict()["failure_penalty"] == 1.0


def test_the_failure_benchmark_small_budget():
    """bench_failures.py's exact result on 2,000 requests (bound 0.12: 5 standard deviations
    of the relative error at k = 5)."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks/bench_failures.py"), "--requests", "2000",
                           "--bound", "0.12"], capture_output=True, text=True, timeout=600, cwd=ROOT, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1].startswith("max_rel_error=") and float(lines[-1].split("=")[1]) <= 0.12
    assert sum(1 for line in lines if "p^k inside" in line or "p^k outside" in line) == 5


def test_p99_against_energy_figure_plots_each_method_at_its_summary_point():
    import pandas as pd
    from test_results import make_requests, make_run

    from yafs_safetail import results
    from yafs_safetail.results.figures import run_figures as figures

    requests = make_requests(np.random.default_rng(5), n_train=20, n_test=30)
    rng = np.random.default_rng(6)
    requests = requests.assign(end_reason="reply", lost=0, server_energy_j=rng.uniform(5, 40, len(requests)),
                               radio_energy_j=0.5, saved_energy_j=0.0)
    requests["energy_j"] = requests["server_energy_j"] + requests["radio_energy_j"]
    built = figures.build_figures(requests, make_run(use_case=1, beta=10))
    axes = built["energy"].axes[0]
    summary = results.summarize(requests)
    points = pd.DataFrame([c.get_offsets()[0] for c in axes.collections], columns=["energy", "p99"])
    assert len(points) == len(summary)
    np.testing.assert_allclose(sorted(points["energy"]), sorted(summary["energy_j_per_request"]))
    assert "no energy columns" not in axes.get_title()
