"""The pre-drawn world: determinism, common random numbers, Eq. 4 target, state derivation."""

from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.calibration import TARGET_COMPUTES, CalibrationError, WorldSettings
from yafs_safetail.edge.latency import target_latency_s
from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import USE_CASES, UnknownUseCaseError, get_use_case, knee_processes
from yafs_safetail.edge.world import (
    WorldError,
    build_world,
    cpu_utilisation,
    memory_utilisation,
    target_compute_by_request_s,
    trace_inputs,
    worst_case_copy_latency_s,
)

ROOT = Path(__file__).resolve().parents[1]


def trace_max_predictor(inputs_without_model):
    """A compute 'model' answering the slowest measured time at k (an upper bound)."""
    slowest = inputs_without_model.max_compute_by_k_s
    return lambda gamma, k: slowest[np.asarray(k) - 1]


def inputs_for(traces, uc):
    rough = trace_inputs(traces, uc, lambda g, k: np.zeros(len(k)))
    median = rough.median_compute_by_k_s
    return trace_inputs(traces, uc, lambda g, k: median[np.asarray(k) - 1])


def scenario(name="paper_5servers"):
    return load_scenario(ROOT / "topologies" / f"{name}.json", ROOT / "placements" / f"{name}.json")


def test_same_seed_and_phase_give_identical_world(traces):
    uc = get_use_case(1)
    inputs = inputs_for(traces, uc)
    a = build_world(scenario(), uc, inputs, 600, seed=3, phase="test")
    b = build_world(scenario(), uc, inputs, 600, seed=3, phase="test")
    np.testing.assert_array_equal(a.copy_latency_table_s(), b.copy_latency_table_s())
    np.testing.assert_array_equal(a.target_s, b.target_s)
    c = build_world(scenario(), uc, inputs, 600, seed=3, phase="train")
    d = build_world(scenario(), uc, inputs, 600, seed=4, phase="test")
    assert not np.array_equal(a.request_row, c.request_row)
    assert not np.array_equal(a.rtt_s, d.rtt_s)


def test_request_stream_does_not_depend_on_the_topology(traces):
    uc = get_use_case(2)
    inputs = inputs_for(traces, uc)
    five = build_world(scenario(), uc, inputs, 300, seed=1, phase="test")
    three = build_world(scenario("3servers"), uc, inputs, 300, seed=1, phase="test")
    np.testing.assert_array_equal(five.input_bytes, three.input_bytes)
    np.testing.assert_array_equal(five.user_uplink_bps, three.user_uplink_bps)
    np.testing.assert_array_equal(five.load_row, three.load_row)


def test_load_trace_advances_one_row_per_step_and_restarts_each_episode(traces):
    uc = get_use_case(1)
    world = build_world(scenario(), uc, inputs_for(traces, uc), 1000, seed=2, phase="test", episode_steps=256)
    steps = np.diff(world.load_row)
    inside = np.ones(999, dtype=bool)
    inside[[255, 511, 767]] = False
    assert np.all((steps[inside] == 1) | (steps[inside] == -1439))
    levels = traces.load.levels(4)
    for server, device in enumerate(world.scenario.server_load_devices):
        np.testing.assert_array_equal(world.background_users[:, server], levels[world.load_row, device])


def test_target_is_eq4_with_median_compute_at_nu(traces):
    uc = get_use_case(3)
    inputs = inputs_for(traces, uc)
    world = build_world(scenario(), uc, inputs, 50, seed=5, phase="test")
    np.testing.assert_array_equal(world.target_compute_s, inputs.median_compute_by_k_s[uc.nu - 1])
    expected = target_latency_s(
        world.input_bytes[7], world.est_output_bytes[7], world.user_uplink_bps[7],
        world.user_downlink_bps[7], world.median_propagation_s, world.target_compute_s[7],
    )
    assert world.target_s[7] == pytest.approx(expected)
    np.testing.assert_array_equal(world.est_output_bytes, world.input_bytes)  # denoised audio


def test_higher_contention_never_gives_more_bandwidth(traces):
    uc = get_use_case(1)
    world = build_world(scenario(), uc, inputs_for(traces, uc), 200, seed=5, phase="test")
    # The same quantile draw maps to each level's pool; pools shrink with contention in the median.
    medians = np.median(world.server_uplink_by_level_bps, axis=(0, 1))
    assert np.all(np.diff(medians) < 0)


def test_observation_reports_the_state(traces):
    uc = get_use_case(2)
    world = build_world(scenario(), uc, inputs_for(traces, uc), 20, seed=5, phase="test")
    active = np.array([0, 1, 2, 3, 4])
    obs = world.observation(4, active)
    assert obs.n_servers == 5
    np.testing.assert_array_equal(obs.server_active_users, active)
    assert obs.server_uplink_bps[2] == world.server_uplink_by_level_bps[4, 2, 2]
    np.testing.assert_allclose(obs.server_median_propagation_s, [0.051, 0.126, 0.513, 0.676, 0.712], atol=0.01)
    assert obs.gamma.shape == (1,)
    assert obs.input_bytes == world.input_bytes[4]
    assert np.all(np.diff(obs.server_memory_util) > 0)
    assert obs.server_cpu_util[1] == pytest.approx(779 / 1600)


def test_utilisation_from_published_figures():
    assert memory_utilisation(0) == 0
    assert memory_utilisation(1) == pytest.approx(829 / 16384)
    assert memory_utilisation(5) == pytest.approx(853 / 16384)
    assert cpu_utilisation(2) == pytest.approx(2 * 740 / 1600)
    assert np.all(cpu_utilisation(np.arange(6)) <= 1)


@pytest.mark.parametrize("number", [1, 2, 3])
def test_nu_is_the_knee_of_the_shipped_compute_trace(traces, number):
    uc = get_use_case(number)
    inputs = inputs_for(traces, uc)
    assert uc.nu == knee_processes(inputs.median_compute_by_k_s)


@pytest.mark.parametrize("number", [1, 2, 3])
def test_fallback_is_not_below_the_worst_case_edge_latency(traces, number):
    uc = get_use_case(number)
    rough = trace_inputs(traces, uc, lambda g, k: np.zeros(len(k)))
    bounded = trace_inputs(traces, uc, trace_max_predictor(rough))
    assert uc.fallback_latency_s >= worst_case_copy_latency_s(bounded, uc, max_load=4)


def test_knee_rule():
    assert knee_processes([1.0, 1.1, 1.2, 2.0, 3.0]) == 3
    assert knee_processes([1.0, 2.0, 3.0]) == 1  # straight line: no knee
    assert knee_processes([1.0, 3.0, 3.5, 3.8]) == 1  # concave: no knee


def test_bad_parameters_are_refused_and_the_fallback_covers_slow_worlds(traces):
    uc = get_use_case(1)
    inputs = inputs_for(traces, uc)
    with pytest.raises(WorldError, match="max_load: 6"):
        build_world(scenario(), uc, inputs, 10, seed=1, phase="test", max_load=6)
    with pytest.raises(WorldError, match="seed"):
        build_world(scenario(), uc, inputs, 10, seed=-1, phase="test")
    # A world whose edge replies can be slower than the use case's on-device fallback
    # raises the fallback to its worst-case edge latency (assumption iv's tolerance bound).
    slow = trace_inputs(traces, uc, lambda g, k: np.full(len(k), 100.0))
    worst_s = worst_case_copy_latency_s(slow, uc, max_load=4)
    assert worst_s > uc.fallback_latency_s
    world = build_world(scenario(), uc, slow, 10, seed=1, phase="test")
    assert worst_s <= world.fallback_latency_s <= worst_s + 0.1
    with pytest.raises(UnknownUseCaseError, match="use case: 4"):
        get_use_case(4)
    assert sorted(USE_CASES) == [1, 2, 3]


def test_a_load_trace_shorter_than_an_episode_is_refused(tmp_path):
    import shutil

    from yafs_safetail.edge.inputs import load_inputs, load_scenario_for
    from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY, REPOSITORY
    from yafs_safetail.edge.world import WorldError, build_world

    traces = tmp_path / "traces"
    shutil.copytree(REPOSITORY / "traces", traces, ignore=shutil.ignore_patterns("*.py", "README.md"))
    rows = (traces / "load.csv").read_text().splitlines()[:6]
    (traces / "load.csv").write_text("\n".join(rows) + "\n")
    use_case = get_use_case(1)
    inputs = load_inputs(use_case, traces)
    scenario = load_scenario_for(inputs, DEFAULT_TOPOLOGY, DEFAULT_PLACEMENT)
    with pytest.raises(WorldError, match=r"load\.csv: rows: 5 minutes, but an episode \(α_s\) needs at least 256"):
        build_world(scenario, use_case, inputs, 10, seed=0, phase="test")
    build_world(scenario, use_case, inputs, 10, seed=0, phase="test", episode_steps=5)  # fits


def _inputs_scaling_with_gamma(traces, uc):
    """Inputs whose compute 'model' grows with the first Γ column (UC2, UC3: the file size)."""
    rough = trace_inputs(traces, uc, lambda g, k: np.zeros(len(k)))
    median_by_k, typical = rough.median_compute_by_k_s, float(np.median(rough.request_gamma[:, 0]))
    return trace_inputs(traces, uc, lambda g, k: median_by_k[np.asarray(k) - 1]
                        * (0.5 + 0.5 * np.asarray(g)[:, 0] / typical))


def test_request_target_compute_is_the_trace_median_scaled_to_the_input(traces):
    uc = get_use_case(3)
    inputs = _inputs_scaling_with_gamma(traces, uc)
    trace = build_world(scenario(), uc, inputs, 300, seed=5, phase="test")
    request = build_world(scenario(), uc, inputs, 300, seed=5, phase="test",
                          settings=WorldSettings(target_compute="request"))
    median_s = inputs.median_compute_by_k_s[uc.nu - 1]
    np.testing.assert_array_equal(trace.target_compute_s, np.full(300, median_s))
    predicted_s = inputs.predict_compute_s(request.gamma, np.full(300, uc.nu))
    trace_predicted_s = inputs.predict_compute_s(inputs.request_gamma,
                                                 np.full(inputs.request_gamma.shape[0], uc.nu))
    np.testing.assert_allclose(request.target_compute_s,
                               median_s * predicted_s / np.median(trace_predicted_s))
    # A longer input gets a longer C(s_j), and the trace's own inputs centre on its median.
    order = np.argsort(predicted_s)
    assert np.all(np.diff(request.target_compute_s[order]) >= 0)
    assert request.target_compute_s.min() < median_s < request.target_compute_s.max()
    centred = target_compute_by_request_s(inputs, inputs.request_gamma, uc.nu, "request")
    assert np.median(centred) == pytest.approx(median_s)
    # Only τ's compute term changes; every latency the methods see is the same world.
    np.testing.assert_allclose(request.target_s - trace.target_s,
                               request.target_compute_s - trace.target_compute_s, atol=1e-12)
    np.testing.assert_array_equal(request.compute_by_processes_s, trace.compute_by_processes_s)
    np.testing.assert_array_equal(request.rtt_s, trace.rtt_s)


def test_both_target_computes_agree_where_gamma_is_only_the_processes(traces):
    uc = get_use_case(1)  # Γ = the number of parallel processes alone: every input is alike
    inputs = inputs_for(traces, uc)
    worlds = [build_world(scenario(), uc, inputs, 200, seed=3, phase="train",
                          settings=WorldSettings(target_compute=reading)) for reading in TARGET_COMPUTES]
    np.testing.assert_array_equal(worlds[0].target_s, worlds[1].target_s)


def test_an_unknown_target_compute_is_refused():
    with pytest.raises(CalibrationError, match="target_compute='mean' is out of range"):
        WorldSettings(target_compute="mean")
