"""Failures in the edge world: lost copies, why each request ended, and nothing moved without them."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from in_process import run_usecase_here

from yafs_safetail import results
from yafs_safetail.edge.calibration import LANDED
from yafs_safetail.edge.failures import DownIntervals, FailureSettings
from yafs_safetail.edge.world import PHASE_STREAMS, build_world
from yafs_safetail.methods.baselines import Oracle, RandX
from yafs_safetail.record import RequestRecord
from yafs_safetail.settings.experiment import ExperimentConfig, ExperimentError
from yafs_safetail.sim.runner import simulate
from yafs_safetail.worlds.recipe import world_recipe

ROOT = Path(__file__).resolve().parents[1]
STEP_S = 60.0
#: A time-out longer than any UC1 copy's latency in these worlds.
LONG_TIMEOUT_S = 30.0


def _world(uc1, n_steps=120, seed=5, **keywords):
    """A UC1 test world whose busiest minutes fill the servers (so some copies are refused)."""
    use_case, scenario, inputs = uc1
    return build_world(scenario, use_case, inputs, n_steps, seed=seed, phase="test",
                       settings=dataclasses.replace(LANDED, load_peak_users=5.0), **keywords)


def _paper_fields(record: RequestRecord) -> tuple:
    """Every field a record had before failures and energy."""
    return tuple(getattr(record, f.name) for f in dataclasses.fields(record)
                 if f.name not in ("lost", "end_reason", "server_energy_j", "radio_energy_j",
                                   "saved_energy_j"))


def test_failures_stream_is_last_and_moves_no_other_draw(uc1):
    assert PHASE_STREAMS[:5] == ("requests", "user_bandwidth", "episodes", "servers", "failures")
    plain = _world(uc1)
    failing = _world(uc1, failures=FailureSettings.for_unavailability(0.3))
    for item in dataclasses.fields(plain):
        value = getattr(plain, item.name)
        if isinstance(value, np.ndarray):
            assert np.array_equal(value, getattr(failing, item.name)), item.name
    assert plain.down_intervals is None and math.isinf(plain.timeout_s)
    assert failing.down_intervals is not None and math.isfinite(failing.timeout_s)


def test_failures_off_leaves_every_record_as_without_the_settings(uc1):
    plain = _world(uc1)
    # Failures off in every spelling: no argument, default settings, a repair time alone.
    for same in (_world(uc1, failures=FailureSettings()), _world(uc1, failures=FailureSettings(mttr_s=5.0)),
                 _world(uc1, failures=FailureSettings.for_unavailability(0.0))):
        for make in (lambda n: Oracle(n, np.random.default_rng(1)), lambda n: RandX(n, np.random.default_rng(1), 2)):
            before = simulate(plain, make(plain.n_servers))
            after = simulate(same, make(same.n_servers))
            assert [_paper_fields(r) for r in before] == [_paper_fields(r) for r in after]
            assert [(r.lost, r.end_reason, r.energy_j) for r in before] == \
                [(r.lost, r.end_reason, r.energy_j) for r in after]
            assert all(r.lost == 0 and r.end_reason == ("all_refused" if r.fallback else "reply")
                       for r in after)


def test_a_configuration_without_the_new_settings_draws_the_same_world():
    recipe = world_recipe(ExperimentConfig(use_case=1, steps_scale=0.02))
    assert not recipe.failures.enabled and recipe.failures.timeout_s is None
    with pytest.raises(ExperimentError, match="--failure-probability: give it or --failure-mttf-s"):
        world_recipe(ExperimentConfig(use_case=1, failure_probability=0.2, failure_mttf_s=10.0))
    with pytest.raises(ExperimentError, match="--server-max-w"):
        world_recipe(ExperimentConfig(use_case=1, server_idle_w=30.0, server_max_w=20.0))


def _copy_times(world, step: int, server: int, emit_s: float) -> tuple[bool, float, float, float]:
    """(admitted, arrival, compute, reply time) of a copy, summed hop by hop as the core does."""
    busy = int(world.background_users[step, server])
    level = min(busy, world.n_contention_levels - 1)
    input_s = float(world.input_transfer_by_level_s[step, server, level])
    output_s = float(world.output_transfer_by_level_s[step, server, level])
    rtt_s = float(world.rtt_s[step, server])
    arrival_s = (emit_s + input_s) + (rtt_s + input_s)
    if busy >= world.max_load:
        return False, arrival_s, math.nan, math.inf
    compute_s = float(world.compute_by_processes_s[step, server, busy])
    return True, arrival_s, compute_s, ((arrival_s + compute_s) + (output_s + rtt_s)) + output_s


def _find_steps(world, n_steps: int) -> tuple[int, int]:
    """A step with at least two admitted copies, and one with a refused copy and an admitted one."""
    admitted = world.background_users < world.max_load
    two = next(t for t in range(n_steps) if admitted[t].sum() >= 2)
    mixed = next(t for t in range(n_steps) if t != two and 1 <= admitted[t].sum() < world.n_servers)
    return two, mixed


def test_scripted_outages_give_the_expected_records(uc1):
    plain = _world(uc1, n_steps=200, seed=11)
    n = plain.n_servers
    two, mixed = _find_steps(plain, 200)
    everything_down = 3 if 3 not in (two, mixed) else next(t for t in range(4, 200) if t not in (two, mixed))
    outages: list[list[tuple[float, float]]] = [[] for _ in range(n)]
    # Step `everything_down`: every server down from before its emission to well after.
    for server in range(n):
        outages[server].append((everything_down * STEP_S - 1.0, everything_down * STEP_S + 40.0))
    # Step `two`: the fastest copy's server fails halfway through its compute.
    times = {i: _copy_times(plain, two, i, two * STEP_S) for i in range(n)}
    winner = min((i for i in range(n) if times[i][0]), key=lambda i: (times[i][3], i))
    _, arrival_w, compute_w, _ = times[winner]
    fails_at_s = arrival_w + compute_w / 2
    outages[winner].append((fails_at_s, two * STEP_S + 50.0))
    runner_up = min((i for i in range(n) if times[i][0] and i != winner), key=lambda i: (times[i][3], i))
    # Step `mixed`: every admitted copy's server is down when it arrives; the others refuse.
    admitted_mixed = [i for i in range(n) if plain.background_users[mixed, i] < plain.max_load]
    for server in admitted_mixed:
        outages[server].append((mixed * STEP_S, mixed * STEP_S + 50.0))
    world = dataclasses.replace(plain, down_intervals=DownIntervals.from_lists(outages),
                                timeout_s=LONG_TIMEOUT_S)
    records = {r.step: r for r in simulate(world, Oracle(n, np.random.default_rng(0)))}
    baseline = {r.step: r for r in simulate(plain, Oracle(n, np.random.default_rng(0)))}
    fallback_s = world.fallback_latency_s

    down = records[everything_down]
    assert (down.end_reason, down.lost, down.refused, down.fallback, down.winner) == ("all_lost", n, 0, True, -1)
    assert down.latency_s == LONG_TIMEOUT_S + fallback_s
    assert down.server_energy_j == 0.0 and down.radio_energy_j > 0  # uploads only

    lost_winner = records[two]
    assert (lost_winner.end_reason, lost_winner.lost, lost_winner.winner) == ("reply", 1, runner_up)
    assert lost_winner.latency_s == times[runner_up][3] - two * STEP_S
    per_process_w = world.energy.server.per_process_w
    # The lost copy computed until its server failed; the others their whole compute time.
    expected_server_j = sum(per_process_w * times[i][2] for i in range(n) if times[i][0] and i != winner)
    expected_server_j += per_process_w * (fails_at_s - arrival_w)
    assert lost_winner.server_energy_j == pytest.approx(expected_server_j, rel=1e-12)

    mixed_record = records[mixed]
    assert mixed_record.end_reason == "all_lost"
    assert (mixed_record.lost, mixed_record.refused) == (len(admitted_mixed), n - len(admitted_mixed))
    assert mixed_record.latency_s == LONG_TIMEOUT_S + fallback_s

    untouched = [t for t in records if t not in (two, mixed, everything_down)]
    for step in untouched:  # the other requests are exactly the paper's
        assert _paper_fields(records[step]) == _paper_fields(baseline[step])
        assert records[step].lost == 0


def test_a_first_reply_after_the_time_out_ends_the_request_as_a_timeout(uc1):
    plain = _world(uc1, n_steps=20)
    first = simulate(plain, RandX(plain.n_servers, np.random.default_rng(2), 2))
    replied = [r for r in first if r.end_reason == "reply"]
    timeout_s = float(np.median([r.latency_s for r in replied]))
    world = dataclasses.replace(plain, timeout_s=timeout_s)
    again = simulate(world, RandX(world.n_servers, np.random.default_rng(2), 2))
    for before, after in zip(first, again, strict=True):
        if before.end_reason == "reply" and before.latency_s > timeout_s:
            assert (after.end_reason, after.fallback, after.winner) == ("timeout", True, -1)
            assert after.latency_s == timeout_s + world.fallback_latency_s
        else:
            assert _paper_fields(after) == _paper_fields(before)
    assert any(r.end_reason == "timeout" for r in again)


def _run_usecase(*args: str, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(ROOT / "experiments/run_usecase.py"), *args, "--out", str(out)],
                          capture_output=True, text=True, timeout=900, cwd=ROOT, check=False)


@pytest.mark.parametrize(("content", "expected"), [
    ("server,down_s\n0,1\n", "missing column(s) up_s"),
    ("server,down_s,up_s\n0,10,5\n", "row 2: field up_s: must be after down_s"),
    ("server,down_s,up_s\n0,1,2\n9,1,2\n", "row 3: field server: 9 is not one of the 5 servers"),
    ("server,down_s,up_s\n0,x,2\n", "row 2: field down_s: not a number of seconds: 'x'"),
])
def test_a_bad_down_intervals_file_is_one_line(tmp_path, content, expected):
    bad = tmp_path / "down.csv"
    bad.write_text(content)
    done = _run_usecase("--uc", "1", "--steps-scale", "0.03", "--down-intervals", str(bad), "--no-figures",
                        out=tmp_path / "out")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and expected in lines[0], done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "out").exists()


def test_run_usecase_with_failures_writes_end_reason_and_energy(tmp_path):
    out = tmp_path / "out"
    done = run_usecase_here("--uc", "1", "--seed", "3", "--steps-scale", "0.03", "--failure-probability", "0.3",
                            "--no-figures", "--quiet", "--out", out)
    assert done.returncode == 0, done.stderr[-2000:]
    header = (out / "requests.csv").read_text().splitlines()[0].split(",")
    assert header[-7:] == ["epsilon", "end_reason", "lost", "energy_j", "server_energy_j",
                           "radio_energy_j", "saved_energy_j"]
    requests = results.read_requests_csv(out)
    test = requests[requests["phase"] == "test"]
    assert set(test["end_reason"]) <= {"reply", "all_refused", "all_lost", "timeout"}
    assert (test["end_reason"] == "all_lost").any() and (test["lost"] > 0).any()
    assert (test["energy_j"] > 0).all() and (test["saved_energy_j"] == 0).all()
    summary = results.read_summary_csv(out)
    oracle = summary[summary["method"] == "Oracle"].iloc[0]
    rand1 = summary[summary["method"] == "Rand-1"].iloc[0]
    assert oracle["success_rate"] > rand1["success_rate"]  # redundancy survives failed servers
    assert oracle["energy_j_per_request"] > rand1["energy_j_per_request"]
    run = results.read_run_json(out)
    assert run.extra["failures"]["enabled"] and run.extra["failures"]["unavailability"] == pytest.approx(0.3)
    assert run.extra["energy"]["server"]["max_w"] > run.extra["energy"]["server"]["idle_w"]
