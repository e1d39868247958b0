"""The contention world built from the traces and topology, any Policy in it, the load sweep."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from in_process import Done, run_in_process

from yafs_safetail.contention.run import PolicyDispatcher, run_policy, summarise
from yafs_safetail.contention.world import (
    LINK_MODELS,
    ContentionConfig,
    ContentionError,
    ContentionWorld,
    compute_speed_table,
)
from yafs_safetail.edge.scenario import DEFAULT_TOPOLOGY, REPOSITORY, ScenarioError
from yafs_safetail.edge.topology_io import load_topology
from yafs_safetail.methods.policy import Policy, PolicyError
from yafs_safetail.methods.registry import make_baseline
from yafs_safetail.runs.sweep_config import SweepConfig

SWEEP = REPOSITORY / "experiments" / "load_sweep.py"


def sweep_here(*args: str) -> Done:
    """``load_sweep.py ARGS`` in this process (tests/in_process.py: TensorFlow imported once)."""
    from yafs_safetail.commands import load_sweep

    return run_in_process(load_sweep.main, *args)


def policy(name: str, seed: int = 0):
    return make_baseline(name, 5, np.random.default_rng(seed))


@pytest.fixture(scope="module")
def busy_world() -> ContentionWorld:
    return ContentionWorld(ContentionConfig(n_requests=3000, users=20, load=0.6, seed=4, queue=True,
                                            block_requests=1000))


@pytest.mark.parametrize("links", LINK_MODELS)
def test_one_user_alone_gets_eq1_latency(links):
    # Requests far apart, no background: every copy runs alone, so its latency is Eq. 1 with
    # the one-process compute time (transfers and RTT at contention level 0), however the links
    # are shared.
    world = ContentionWorld(ContentionConfig(n_requests=50, users=1, rate_per_user_hz=1e-3,
                                             background=False, block_requests=50, links=links))
    run = run_policy(world, policy("MinProp-1"))
    block = world.block_world(0)
    server = 0  # the nearest server in the paper topology
    expected = (2 * block.input_transfer_by_level_s[:, server, 0] + 2 * block.rtt_s[:, server]
                + block.compute_by_processes_s[:, server, 0] + 2 * block.output_transfer_by_level_s[:, server, 0])
    np.testing.assert_allclose(run.result.latency_s, expected, rtol=1e-9)


class RecordingPairs:
    """Two random servers per request; keeps every outcome."""

    mode = "all"
    wants_outcomes = True

    def __init__(self, n_servers: int) -> None:
        self.rng = np.random.default_rng(1)
        self.n_servers = n_servers
        self.outcomes: list = []

    def choose(self, request, active_users):
        return tuple(self.rng.choice(self.n_servers, size=2, replace=False).tolist())

    def hedge_delay_s(self):
        return float("inf")

    def completed(self, reply):
        self.outcomes.append(reply)


def test_shared_links_keep_each_transfer_between_its_fastest_and_slowest_level():
    # Under load (background on, two copies per request), a shared transfer changes pace as
    # others come and go: the time it takes lies between its times at the lowest and highest
    # contention levels. Read at the start instead, it is exactly one level's time.
    from yafs_safetail.contention.engine import run_engine

    config = ContentionConfig(n_requests=2000, users=20, load=0.6, seed=4, queue=True, block_requests=2000)
    levels_seen = {}
    for links in LINK_MODELS:
        world = ContentionWorld(replace(config, links=links))
        tables = world.block(0)
        dispatcher = RecordingPairs(world.n_servers)
        run_engine(world.engine_settings(), world.emit_s.tolist(), 2000, world.block, dispatcher)
        levels = world.inputs.n_contention_levels
        inside = exact = 0
        for outcome in dispatcher.outcomes:
            if outcome.fallback:
                continue
            base = outcome.winner * levels
            by_level = tables.input_transfer_s[outcome.request][base:base + levels]
            inside += min(by_level) - 1e-9 <= outcome.input_transfer_s <= max(by_level) + 1e-9
            exact += any(abs(outcome.input_transfer_s - t) <= 1e-12 for t in by_level)
        levels_seen[links] = (inside, exact, len(dispatcher.outcomes))
    inside, exact, total = levels_seen["shared"]
    assert inside == total and exact < total  # some transfers changed pace on the way
    inside, exact, total = levels_seen["at-start"]
    assert inside == exact == total


def test_same_seed_same_results_and_common_random_numbers(busy_world):
    again = ContentionWorld(busy_world.config)
    first, second = run_policy(busy_world, policy("Rand-2")), run_policy(again, policy("Rand-2"))
    assert np.array_equal(first.result.latency_s, second.result.latency_s)
    assert np.array_equal(busy_world.emit_s, again.emit_s)
    other = ContentionWorld(replace(busy_world.config, seed=5))
    assert not np.array_equal(other.emit_s, busy_world.emit_s)


def test_redundancy_costs_under_load(busy_world):
    # Past the point where five copies per request overload the servers, Oracle loses to
    # single dispatch; with cancellation off, copies also cost more server time.
    oracle, single = summarise(run_policy(busy_world, policy("Oracle"))), summarise(
        run_policy(busy_world, policy("MinLoad-1")))
    assert oracle["p99_s"] > single["p99_s"]
    assert oracle["server_s_per_request"] > 2 * single["server_s_per_request"]
    no_cancel = summarise(run_policy(busy_world, policy("Rand-2"), cancel=False))
    cancel = summarise(run_policy(busy_world, policy("Rand-2")))
    assert no_cancel["server_s_per_request"] > cancel["server_s_per_request"]
    assert no_cancel["cancelled_per_request"] == 0 < cancel["cancelled_per_request"]


def test_hedge_and_tied_run_and_hedge_sends_few_extra_copies(busy_world):
    hedge = summarise(run_policy(busy_world, policy("Hedge")))
    tied = summarise(run_policy(busy_world, policy("Tied")))
    assert 1.0 <= hedge["mean_n_selected"] < 1.3
    assert tied["mean_n_selected"] == 2.0 and np.isfinite(tied["p99_s"])


def test_hedge_and_tied_are_refused_in_the_single_user_world(paper_scenario):
    from yafs_safetail.sim.hooks import EdgeModel
    from yafs_safetail.sim.selection import PolicySelection

    world = ContentionWorld(ContentionConfig(n_requests=10, users=1)).block_world(0)
    with pytest.raises(PolicyError, match="Hedge: dispatch 'hedge' needs the contention world"):
        PolicySelection(EdgeModel(world), policy("Hedge"))


def test_load_sets_the_arrival_rate():
    world = ContentionWorld(ContentionConfig(n_requests=20_000, users=10, load=0.5, background=False))
    assert world.offered_load() == pytest.approx(0.5, rel=0.03)
    assert world.rate_for_load(1.0) == pytest.approx(world.total_slots / world.mean_service_s)


def test_heterogeneous_servers_from_the_topology(tmp_path):
    data = json.loads(DEFAULT_TOPOLOGY.read_text())
    servers = [e for e in data["entity"] if e["type"] == "edge_server"]
    servers[0]["IPT"] = 2e9
    servers[1]["capacity"] = 8
    path = tmp_path / "hetero.json"
    path.write_text(json.dumps(data))
    world = ContentionWorld(ContentionConfig(n_requests=10, users=1, topology=path))
    assert world.capacity[:2] == (4, 8) and world.total_slots == 24
    speeds = world.engine_settings().servers
    assert speeds[0].speed[1] == pytest.approx(2.0) and speeds[2].speed[1] == pytest.approx(1.0)
    assert world.observation(0, [0] * 5).server_max_load.tolist() == [4, 8, 4, 4, 4]
    servers[1]["capacity"] = 0
    path.write_text(json.dumps(data))
    with pytest.raises(ScenarioError, match=r"hetero.json: entity\[\d\]\.capacity: not a positive integer: 0"):
        load_topology(path)


def test_speed_table_follows_the_traced_compute_times():
    table = compute_speed_table(np.array([1.0, 1.5, 2.0]), 1.0, 6)
    assert table[1:] == pytest.approx((1.0, 1 / 1.5, 0.5, 0.5 * 3 / 4, 0.5 * 3 / 5, 0.5 * 3 / 6))


def test_arrivals_from_a_trace_and_its_errors(tmp_path):
    good = tmp_path / "arrivals.csv"
    good.write_text("time_s,user\n2.0,1\n0.5,0\n1.0,2\n")
    world = ContentionWorld(ContentionConfig(users=3, arrivals_csv=good, load=None))
    assert world.emit_s.tolist() == [0.5, 1.0, 2.0] and world.user.tolist() == [0, 2, 1]
    for text, message in (("t,u\n1,0\n", "header: expected the columns time_s,user"),
                          ("time_s,user\n1,7\n", "line 2: user 7 is not in 0..2"),
                          ("time_s,user\nx,0\n", "line 2: not a number"),
                          ("time_s,user\n", "rows: no arrivals")):
        good.write_text(text)
        with pytest.raises(ContentionError, match=message):
            ContentionWorld(ContentionConfig(users=3, arrivals_csv=good, load=None))


@pytest.mark.parametrize(("changes", "message"), [
    ({"users": 0}, "^users: expected a positive integer"),
    ({"load": None}, "give one of them"),
    ({"rate_per_user_hz": float("nan")}, "^rate_per_user_hz: expected a positive number"),
    ({"load": -1.0}, "^load: expected a positive number"),
    ({"links": "both"}, "^links: expected one of shared, at-start, got 'both'"),
])
def test_bad_settings_are_one_line(changes, message):
    with pytest.raises(ContentionError, match=message):
        ContentionWorld(replace(ContentionConfig(n_requests=10), **changes))


def test_load_sweep_small_budget(tmp_path):
    out = tmp_path / "sweep"
    command = [sys.executable, str(SWEEP), "--users", "10", "--loads", "0.2,0.8", "--steps-scale", "0.02",
               "--methods", "Oracle,MinLoad-1,Tied", "--seed", "3", "--out", str(out)]
    done = sweep_here(*command[2:])
    assert done.returncode == 0, done.stderr
    frame = pd.read_csv(out / "sweep.csv")
    for column in ("load", "method", "n_requests", "p50_s", "p99_s", "mean_n_selected", "fallback_rate"):
        assert column in frame.columns
    # Both SafeTails by default, each named for its learner, before the fixed methods.
    assert list(frame[frame["load"] == 0.2]["method"]) == ["SafeTail", "SafeTail-CA", "Oracle", "MinLoad-1", "Tied"]
    assert (frame["n_requests"] == 380).all() and set(frame["load"]) == {0.2, 0.8}
    report = (out / "SWEEP.md").read_text()
    assert "SafeTail: preset `paper`, learner `target-vector`, reward `paper`, dispatch `all`" in report
    assert ("SafeTail-CA: preset `tuned`, learner `value` (3 networks averaged), reward `latency-cost`, "
            "dispatch `tied`" in report)
    assert "| SafeTail-CA p99 <= 1.05x best fixed at load 0.8 |" in report
    assert "| load | SafeTail | SafeTail-CA | Oracle | MinLoad-1 | Tied |" in done.stdout
    safetails = json.loads((out / "run.json").read_text())["safetails"]
    assert [(s["name"], s["learner"], s["preset"], s["dispatch"]) for s in safetails] == [
        ("SafeTail", "target-vector", "paper", "all"), ("SafeTail-CA", "value", "tuned", "tied")]
    for name in ("SWEEP.md", "sweep.png", "sweep_latency.png", "run.json", "load-0.2/sweep.csv",
                 "load-0.8/run.json", "campaign.json"):
        assert (out / name).is_file(), name
    # Each load's run.log: the command and what each method measured there.
    load_log = (out / "load-0.8" / "run.log").read_text()
    assert "load-0.8 sweep: done" in load_log and "load 0.8: Tied" in load_log and "--users 10" in load_log
    first = (out / "sweep.csv").read_bytes()
    # Each load is a campaign run: rerunning resumes and recomputes nothing.
    again = sweep_here(*command[2:])
    assert again.returncode == 0, again.stderr
    assert "2 runs: 0 computed now, 2 done earlier" in again.stderr
    assert (out / "sweep.csv").read_bytes() == first
    # A folder that is not a sweep's is refused and left as it was.
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep")
    refused = subprocess.run([*command[:-1], str(other)], capture_output=True, text=True, timeout=600)
    assert refused.returncode == 2 and "is not a load sweep's folder" in refused.stderr
    assert [p.name for p in other.iterdir()] == ["notes.txt"]


@pytest.mark.slow  # a sweep's loads are campaign runs; the golden campaign runs with --workers 2
def test_load_sweep_gives_the_same_bytes_with_two_workers(tmp_path):
    command = [sys.executable, str(SWEEP), "--users", "10", "--loads", "0.2,0.8", "--steps-scale", "0.02",
               "--methods", "Oracle,MinLoad-1,Tied", "--seed", "3"]
    subprocess.run([*command, "--out", str(tmp_path / "one")], check=True, capture_output=True, timeout=600)
    subprocess.run([*command, "--out", str(tmp_path / "two"), "--workers", "2"], check=True,
                   capture_output=True, timeout=600)
    for name in ("sweep.csv", "load-0.2/sweep.csv", "load-0.8/sweep.csv"):
        assert (tmp_path / "two" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name


def test_load_sweep_bad_input_is_one_line(tmp_path):
    done = subprocess.run([sys.executable, str(SWEEP), "--loads", "0.5,x", "--out", str(tmp_path / "s")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "--loads" in done.stderr and "Traceback" not in done.stderr
    done = subprocess.run([sys.executable, str(SWEEP), "--methods", "Best-3", "--out", str(tmp_path / "s")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "unknown baseline 'Best-3'" in done.stderr
    assert not Path(tmp_path / "s").exists()


@pytest.mark.parametrize(("script", "args", "last"), [
    ("bench_queueing.py", ["--requests", "3000", "--servers", "3"], "max_rel_error="),
    ("bench_multiuser.py", ["--sizes", "500,1000", "--users", "20"], "requests=1000 seconds="),
])
def test_benchmarks_small_budget(script, args, last):
    done = subprocess.run([sys.executable, str(REPOSITORY / "benchmarks" / script), *args],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1].startswith(last)


def test_users_have_their_own_conditions(tmp_path):
    base = ContentionConfig(n_requests=400, users=6, load=0.2, block_requests=200, seed=2)
    same = ContentionWorld(base)
    generated = ContentionWorld(replace(base, user_conditions="generated"))
    assert generated.conditions.shape == (6, 5) and generated.conditions.min() >= 1
    assert np.all(np.abs(generated.conditions - same.conditions) <= 1)
    assert not np.array_equal(generated.conditions, same.conditions)
    # A user at the topology's conditions sees exactly the topology's RTTs; the others differ
    # where their conditions do.
    for index in (0, 1):
        ours, theirs = generated.block(index), same.block(index)
        users = generated.user[index * 200:(index + 1) * 200]
        for r, user in enumerate(users):
            equal = generated.conditions[user] == same.conditions[user]
            rtt, ref = np.asarray(ours.propagation_s[r]), np.asarray(theirs.propagation_s[r])
            assert np.array_equal(rtt[equal], ref[equal])
    user = int(generated.user[5])
    assert generated.observation(5, [0] * 5).server_median_propagation_s.tolist() == pytest.approx(
        generated.user_median_propagation_s[user].tolist())
    listed = tmp_path / "users.json"
    listed.write_text(json.dumps({"users": [{"conditions": [5, 5, 5, 5, 5]}] * 6}))
    far = ContentionWorld(replace(base, user_conditions=listed))
    assert far.target_s(0) > same.target_s(0)
    listed.write_text(json.dumps({"users": [{"conditions": [9, 1, 1, 1, 1]}] * 6}))
    with pytest.raises(ContentionError, match=r"users.json: users\[0\]\.conditions: expected 5 conditions"):
        ContentionWorld(replace(base, user_conditions=listed))


def test_the_contention_reward_only_changes_a_miss_with_all_servers():
    from yafs_safetail.methods.safetail.reward import reward, reward_no_free_miss

    delta = 0.003
    assert reward(2.0, 1.0, 5, 5, delta) == 0.0
    assert reward_no_free_miss(2.0, 1.0, 5, 5, delta) == pytest.approx(-delta * np.e)
    assert reward_no_free_miss(2.0, 1.0, 4, 5, delta) == pytest.approx(reward(2.0, 1.0, 4, 5, delta))
    for case in ((0.5, 1.0, 1), (0.5, 1.0, 3), (1.0, 1.0, 5), (3.0, 1.0, 2)):
        assert reward_no_free_miss(*case, 5, delta) == reward(*case, 5, delta)


def test_safetail_rejects_an_unknown_reward():
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy

    class Learner:
        n_servers = 5

    with pytest.raises(PolicyError, match="SafeTail: unknown reward 'best'"):
        SafeTailPolicy(5, np.random.default_rng(0), learner=Learner(), scales=None,  # type: ignore[arg-type]
                       training=True, reward_name="best")


def test_load_sweep_never_writes_into_another_campaign(tmp_path):
    other = tmp_path / "campaign"
    other.mkdir()
    (other / "campaign.json").write_text("{}")
    (other / "SWEEP.md").write_text("mine")
    done = subprocess.run([sys.executable, str(SWEEP), "--loads", "0.5", "--out", str(other)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "is not a load sweep's folder" in done.stderr
    assert (other / "SWEEP.md").read_text() == "mine"


def test_a_users_own_target_follows_the_requests_input(tmp_path):
    # Users 0-2 at the topology's own conditions, user 3 farther: τ is then built per user, and
    # for users 0-2 it must be the block world's τ, compute term included (UC3's C(s_j) follows
    # each clip: docs/deviations.md D11).
    base = ContentionConfig(use_case=3, n_requests=300, users=4, load=0.2, block_requests=300, seed=4)
    topology = ContentionWorld(base)
    conditions = [int(c) for c in topology.scenario.server_conditions]
    listed = tmp_path / "users.json"
    listed.write_text(json.dumps({"users": [{"conditions": conditions}] * 3 + [{"conditions": [5] * 5}]}))
    per_user = ContentionWorld(replace(base, user_conditions=listed))
    at_topology = [r for r in range(300) if per_user.user[r] != 3]
    assert 0 < len(at_topology) < 300
    np.testing.assert_allclose([per_user.target_s(r) for r in at_topology],
                               [topology.target_s(r) for r in at_topology], rtol=1e-12)
    world = per_user.block_world(0)
    assert world.settings.target_compute == "request" and np.ptp(world.target_compute_s) > 0.5


def test_the_observed_load_target_is_eq4_at_nu_and_grows_with_the_load():
    world = ContentionWorld(ContentionConfig(n_requests=200, users=5, load=0.5, seed=6, queue=True,
                                             block_requests=200))
    nu = world.block_world(0).nu
    traced = world.inputs.median_compute_by_k_s
    eq4 = world.target_s(7)
    # The median server running ν - 1 others: the new copy is the ν-th instance, Eq. 4's own case.
    assert world.observed_load_target_s(7, [nu - 1] * 5) == pytest.approx(eq4)
    idle, busy = world.observed_load_target_s(7, [0] * 5), world.observed_load_target_s(7, [3, 3, 3, 0, 0])
    assert idle == pytest.approx(eq4 - traced[nu - 1] + traced[0])  # UC1: C(s_j) is the trace's median
    assert idle < eq4 < busy == pytest.approx(eq4 - traced[nu - 1] + traced[3])
    # Past the four slots a copy also waits: 8 jobs on 4 slots are two rounds of T(4).
    assert world.observed_load_target_s(7, [7] * 5) == pytest.approx(eq4 - traced[nu - 1] + 2 * traced[3])


class _TargetRecorder(Policy):
    """One copy to server 0; keeps what it saw and the τ of each record it got back."""

    def __init__(self, n_servers, rng):
        super().__init__(n_servers, rng)
        self.seen: dict[int, list[int]] = {}
        self.targets: dict[int, float] = {}

    def choose(self, observation):
        self.seen[observation.step] = observation.server_active_users.tolist()
        return (0,)

    def feedback(self, record):
        self.targets[record.request_id] = record.target_s
        return record


def test_feedback_records_carry_the_target_asked_for():
    world = ContentionWorld(ContentionConfig(n_requests=300, users=10, load=0.6, seed=2, queue=True,
                                             block_requests=300))
    eq4, observed = _TargetRecorder(5, np.random.default_rng(0)), _TargetRecorder(5, np.random.default_rng(0))
    run_policy(world, eq4)
    run_policy(world, observed, target="observed-load")
    assert eq4.targets == {r: pytest.approx(world.target_s(r)) for r in range(300)}
    assert observed.targets == {r: pytest.approx(world.observed_load_target_s(r, observed.seen[r]))
                                for r in range(300)}
    assert observed.targets != eq4.targets
    with pytest.raises(PolicyError, match="target 'queue-aware'"):
        run_policy(world, eq4, target="queue-aware")


def test_load_sweep_target_and_links_options(tmp_path):
    out = tmp_path / "sweep"
    done = sweep_here("--users", "10", "--loads", "0.5", "--steps-scale", "0.02", "--methods", "Oracle",
                      "--target", "observed-load", "--links", "at-start", "--objectives", "target-vector",
                      "--out", str(out))
    assert done.returncode == 0, done.stderr
    run = json.loads((out / "run.json").read_text())
    assert run["target"] == "observed-load" and run["links"] == "at-start"
    settings = json.loads((out / "campaign.json").read_text())["runs"][0]["settings"]
    assert settings["target"] == "observed-load" and settings["links"] == "at-start"
    assert "queue, at-start links, seed 0" in (out / "SWEEP.md").read_text()
    bad = subprocess.run([sys.executable, str(SWEEP), "--target", "queue", "--out", str(tmp_path / "b")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--target" in bad.stderr and len(bad.stderr.splitlines()) == 1
    assert not (tmp_path / "b").exists()


def test_sweep_checks_are_computed_from_the_rows():
    from yafs_safetail.results.sweep_report import sweep_checks

    def row(load, method, p99_s, copies):
        return {"load": load, "method": method, "p99_s": p99_s, "mean_n_selected": copies}

    frame = pd.DataFrame([row(0.1, "SafeTail", 1.02, 3.0), row(0.1, "Tied", 1.1, 2.0), row(0.1, "Oracle", 1.0, 5.0),
                          row(0.9, "SafeTail", 4.0, 3.5), row(0.9, "Tied", 3.7, 2.0), row(0.9, "Oracle", 90.0, 5.0)])
    checks = {claim: (holds, measured) for claim, holds, measured in sweep_checks(frame)}
    assert checks["Oracle p99 at load 0.9 >= 1.5x at load 0.1"] == (True, "90.00x")
    assert checks["SafeTail: fewer copies as load rises"] == (False, "3.00 -> 3.50")
    assert checks["SafeTail p99 <= 1.05x best fixed at load 0.1"] == (True, "1.020 s vs Oracle 1.000 s (1.02x)")
    assert not checks["SafeTail p99 <= 1.05x best fixed at load 0.9"][0]  # 4.0 s against Tied's 3.7 s
    assert checks["SafeTail p99 < Oracle's at load 0.9"][0]
    # One load says nothing of how the copies or Oracle follow the load: those goals are left out.
    single = {claim for claim, _, _ in sweep_checks(frame[frame["load"] == 0.9])}
    assert single == {"SafeTail p99 <= 1.05x best fixed at load 0.9", "SafeTail p99 < Oracle's at load 0.9"}


def test_both_safetails_are_checked_and_neither_is_a_fixed_method():
    from yafs_safetail.results.sweep_report import (
        best_fixed_p99,
        glance_markdown,
        seeds_markdown,
        sweep_checks,
    )
    from yafs_safetail.runs.sweep_learners import SAFETAIL_CA

    def row(load, method, p99_s, copies):
        return {"load": load, "method": method, "p99_s": p99_s, "mean_n_selected": copies}

    frame = pd.DataFrame([row(0.1, "SafeTail", 2.0, 1.0), row(0.1, SAFETAIL_CA, 1.0, 3.5),
                          row(0.1, "Tied", 1.5, 2.0), row(0.1, "Oracle", 1.9, 5.0),
                          row(0.9, "SafeTail", 900.0, 5.0), row(0.9, SAFETAIL_CA, 3.9, 2.2),
                          row(0.9, "Tied", 4.0, 2.0), row(0.9, "Oracle", 990.0, 5.0)])
    # The SafeTails beat Tied at 0.1 but are never "the best fixed method".
    assert best_fixed_p99(frame, 0.1) == ("Tied", 1.5)
    checks = {claim: holds for claim, holds, _ in sweep_checks(frame)}
    assert checks["SafeTail-CA: fewer copies as load rises"] and not checks["SafeTail: fewer copies as load rises"]
    assert checks["SafeTail-CA p99 <= 1.05x best fixed at load 0.9"]
    assert not checks["SafeTail p99 <= 1.05x best fixed at load 0.9"]
    assert checks["SafeTail-CA p99 < Oracle's at load 0.9"] and checks["SafeTail p99 < Oracle's at load 0.9"]
    glance = glance_markdown(frame)
    assert "| load | SafeTail | SafeTail-CA | Tied | Oracle |" in glance
    assert "| 0.9 | 900 | 3.90 | **4.00** | 990 |" in glance and "| 0.9 | 5.00 | 2.20 | 2.00 | 5.00 |" in glance
    report = seeds_markdown({7: frame})
    assert "Each cell: SafeTail's p99" in report and "Each cell: SafeTail-CA's p99" in report
    assert "| 7 | 0.67 (Tied), 3.50 | 0.97 (Tied), 2.20 |" in report
    # The learners are named once each, from the two objectives.
    with pytest.raises(ContentionError, match="objectives"):
        SweepConfig(base=ContentionConfig(), loads=(0.5,), objectives=("value", "value"))
    config = SweepConfig(base=ContentionConfig(), loads=(0.5,), preset="paper", dispatch="all")
    assert [(v.name, v.preset, v.dispatch) for v in config.safetails] == [
        ("SafeTail", "paper", "all"), ("SafeTail-CA", "paper", "all")]
    assert SweepConfig(base=ContentionConfig(), loads=(0.5,), safetail=False).safetails == ()


def test_load_sweep_test_requests_option(tmp_path):
    from yafs_safetail.contention.run import WARMUP_FRACTION

    out = tmp_path / "sweep"
    done = sweep_here("--users", "10", "--loads", "0.5", "--steps-scale", "0.02", "--test-requests", "1000",
                      "--no-safetail", "--methods", "Tied", "--out", str(out))
    assert done.returncode == 0, done.stderr
    # 1,000 test requests whatever --steps-scale (which alone would give 400), warm-up left out.
    assert json.loads((out / "run.json").read_text())["test_requests"] == 1000
    assert json.loads((out / "campaign.json").read_text())["runs"][0]["settings"]["test_requests"] == 1000
    assert pd.read_csv(out / "sweep.csv")["n_requests"].tolist() == [1000 - int(WARMUP_FRACTION * 1000)]
    bad = subprocess.run([sys.executable, str(SWEEP), "--test-requests", "50", "--out", str(tmp_path / "b")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--test-requests: 50 test requests per load" in bad.stderr
    assert len(bad.stderr.splitlines()) == 1 and not (tmp_path / "b").exists()
    with pytest.raises(ContentionError, match="^test_requests_per_load: expected a positive integer, got 0$"):
        SweepConfig(base=ContentionConfig(), loads=(0.5,), test_requests_per_load=0)


def test_the_latency_cost_reward():
    from yafs_safetail.methods.safetail.reward import LOAD_PRICE, latency_score, reward_latency_cost

    # Latency in units of τ on a log scale, less a price per job already on the chosen servers.
    assert latency_score(1.0, 2.0) == pytest.approx(-np.log(0.5))
    assert reward_latency_cost(1.0, 2.0, 0) == latency_score(1.0, 2.0)  # idle servers: copies are free
    assert reward_latency_cost(1.0, 2.0, 7) == pytest.approx(-np.log(0.5) - 7 * LOAD_PRICE)
    assert reward_latency_cost(0.1, 1.0, 1) > 0 > reward_latency_cost(4.0, 1.0, 1)
    assert np.isfinite(reward_latency_cost(0.0, 1.0, 0))
    with pytest.raises(ValueError, match="jobs_on_chosen"):
        reward_latency_cost(1.0, 1.0, -1)
    with pytest.raises(ValueError, match="latency_s"):
        latency_score(-1.0, 1.0)


@pytest.mark.parametrize("dispatch", ["tied", "all"])
def test_the_value_learner_learns_the_latency_score_and_prices_copies_exactly(dispatch):
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import TIED_MIN_COPIES, SafeTailPolicy
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.methods.safetail.reward import LOAD_PRICE, latency_score
    from yafs_safetail.methods.safetail.spaces import (
        StateScales,
        encode_state,
        membership_matrix,
        subset_of,
    )

    world = ContentionWorld(ContentionConfig(n_requests=400, users=20, load=0.8, seed=4, queue=True,
                                             block_requests=400))
    config = replace(get_preset("tuned", 1), objective="value", kappa=1000)  # no round: weights stay
    scales = StateScales.for_use_case(1)

    class Recording(SafeTailPolicy):
        """Keeps what each decision saw and each record, in the order the learner got them."""

        seen: dict
        records: list

        def choose(self, observation):
            self.seen[observation.step] = observation
            return super().choose(observation)

        def feedback(self, outcome):
            record = super().feedback(outcome)
            self.records.append(record)
            return record

    for training in (True, False):
        learner = SafeTailLearner(5, 36, config, 0)
        policy = Recording(5, np.random.default_rng(0), learner=learner, scales=scales, training=training,
                           reward_name="latency-cost", dispatch=dispatch)
        policy.seen, policy.records = {}, []
        run_policy(world, policy)
        records = policy.records
        assert len(records) == 400
        busy = 0
        for record in records:
            jobs = policy.seen[record.step].server_active_users
            chosen_jobs = int(sum(jobs[i] for i in record.servers))
            busy += chosen_jobs > 0
            # The record's reward is the whole latency-cost reward ...
            assert record.reward == pytest.approx(latency_score(record.latency_s, record.target_s)
                                                  - LOAD_PRICE * chosen_jobs)
            if not training:
                # ... and a greedy choice is the best prediction less the price of its copies.
                state = encode_state(policy.seen[record.step], scales)
                outputs = np.asarray(learner.model(state[None, :], training=False))[0]
                scores = outputs - LOAD_PRICE * (membership_matrix(5) @ jobs)
                if dispatch == "tied":
                    # A tied request has a sibling: lone copies are never the greedy choice.
                    scores[membership_matrix(5).sum(axis=1) < TIED_MIN_COPIES] = -np.inf
                assert record.servers == subset_of(int(scores.argmax()), 5)
        assert busy > 20  # servers were busy at dispatch: the price was not always 0
        sizes = {len(record.servers) for record in records}
        if training:
            assert 1 in sizes  # exploration still tries lone copies (and the network learns from them)
        elif dispatch == "tied":
            assert min(sizes) >= TIED_MIN_COPIES
        if training:
            # ... while the network is fitted to the latency score alone.
            targets = learner.training_state()["targets"][:len(records)]
            learned = np.nanmax(targets, axis=1)
            assert np.allclose(learned, [latency_score(r.latency_s, r.target_s) for r in records], rtol=1e-6)


@pytest.mark.parametrize("n_servers", [1, 2])
def test_the_floor_of_two_tied_copies_needs_two_servers(n_servers):
    # With two servers the only subset a tied request may take is both, whatever the network
    # prefers; with one server there is no sibling to send, so the floor does not apply.
    from yafs_safetail.edge.observation import Observation
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.methods.safetail.reward import copy_price
    from yafs_safetail.methods.safetail.spaces import (
        StateScales,
        encode_state,
        membership_matrix,
        state_dim,
        subset_of,
    )

    n = n_servers
    observation = Observation(
        server_uplink_bps=np.full(n, 20e6), server_downlink_bps=np.full(n, 20e6),
        server_memory_util=np.full(n, 0.05), server_cpu_util=np.full(n, 0.5),
        server_active_users=np.arange(n) * 30, server_median_propagation_s=np.full(n, 0.1),
        input_bytes=80e3, est_output_bytes=2e3, gamma=np.array([]), user_location=np.array([0.0, 0.0]),
        user_uplink_bps=20e6, user_downlink_bps=20e6, server_max_load=np.full(n, 4), step=0)
    scales = StateScales.for_use_case(1)
    learner = SafeTailLearner(n, state_dim(n, 0, 2), replace(get_preset("tuned", 1), objective="value"), 0)
    outputs = np.asarray(learner.model(encode_state(observation, scales)[None, :], training=False))[0]
    prices = copy_price(membership_matrix(n) @ observation.server_active_users)
    unfloored = subset_of(int((outputs - prices).argmax()), n)
    # Server 1's 30 jobs price it out: without the floor the choice is server 0 alone.
    assert unfloored == (0,)
    for dispatch, expected in (("tied", tuple(range(n))), ("all", unfloored)):
        policy = SafeTailPolicy(n, np.random.default_rng(0), learner=learner, scales=scales, training=False,
                                reward_name="latency-cost", dispatch=dispatch)
        assert policy.choose(observation) == expected, dispatch


def test_safetail_dispatch_and_value_reward_are_checked():
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.methods.safetail.presets import get_preset
    from yafs_safetail.methods.safetail.spaces import StateScales

    world = ContentionWorld(ContentionConfig(n_requests=300, users=10, load=0.6, seed=2, queue=True,
                                             block_requests=300))
    scales = StateScales.for_use_case(1)
    paper = SafeTailLearner(5, 36, get_preset("paper", 1), 0)
    with pytest.raises(PolicyError, match="latency-cost reward needs a learner with the value objective"):
        SafeTailPolicy(5, np.random.default_rng(0), learner=paper, scales=scales, training=True,
                       reward_name="latency-cost")
    with pytest.raises(PolicyError, match="unknown dispatch 'hedge'"):
        SafeTailPolicy(5, np.random.default_rng(0), learner=paper, scales=scales, training=True, dispatch="hedge")
    tied = SafeTailPolicy(5, np.random.default_rng(0), learner=paper, scales=scales, training=False,
                          dispatch="tied")
    assert PolicyDispatcher(world, tied).mode == "tied" and SafeTailPolicy.dispatch == "all"
    # Tied copies cancel each other once one starts: a copy runs for less server time than with "all".
    race = SafeTailPolicy(5, np.random.default_rng(0), learner=paper, scales=scales, training=False)
    tied_run, race_run = run_policy(world, tied), run_policy(world, race)
    assert tied_run.result.n_copies.mean() > 1.5 and race_run.result.n_copies.mean() > 1.5
    per_copy_s = [run.result.busy_s / run.result.n_copies.sum() for run in (tied_run, race_run)]
    assert per_copy_s[0] < 0.8 * per_copy_s[1], per_copy_s


def test_load_sweep_value_learner_and_tied_dispatch(tmp_path):
    out = tmp_path / "sweep"
    command = [sys.executable, str(SWEEP), "--users", "10", "--loads", "0.5", "--steps-scale", "0.02",
               "--methods", "Tied", "--preset", "tuned", "--objectives", "value", "--safetail-dispatch", "tied",
               "--value-networks", "2", "--seed", "2", "--out", str(out)]
    done = sweep_here(*command[2:])
    assert done.returncode == 0, done.stderr
    [safetail] = json.loads((out / "run.json").read_text())["safetails"]
    assert (safetail["learner"], safetail["dispatch"], safetail["reward"]) == ("value", "tied", "latency-cost")
    assert safetail["n_networks"] == 2
    settings = json.loads((out / "campaign.json").read_text())["runs"][0]["settings"]
    assert (settings["learner"], settings["dispatch"], settings["value_networks"]) == (["value"], "tied", 2)
    frame = pd.read_csv(out / "sweep.csv")
    assert list(frame["method"]) == ["SafeTail-CA", "Tied"]
    assert ("SafeTail-CA: preset `tuned`, learner `value` (2 networks averaged), reward `latency-cost`, "
            "dispatch `tied`, target `eq4`."
            in (out / "SWEEP.md").read_text())
    # (Same seed, same bytes: the golden sweep runs SafeTail-CA with these settings' defaults.)
    bad = subprocess.run([*command[:-1], str(tmp_path / "b"), "--reward", "no-free-miss"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "the value learner has its own reward" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and not (tmp_path / "b").exists()
    bad = subprocess.run([sys.executable, str(SWEEP), "--value-networks", "2", "--objectives", "target-vector",
                          "--out", str(tmp_path / "b")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--value-networks 2: only with the value learner" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and not (tmp_path / "b").exists()
    with pytest.raises(ContentionError, match="only the value learner averages networks"):
        SweepConfig(base=ContentionConfig(), loads=(0.5,), objectives=("target-vector",), n_networks=2)
    # Unless told, the value learner averages DEFAULT_VALUE_NETWORKS networks; §III's has one.
    assert SweepConfig(base=ContentionConfig(), loads=(0.5,), objectives=("value",)).networks_averaged == 3
    assert SweepConfig(base=ContentionConfig(), loads=(0.5,), objectives=("target-vector",)).networks_averaged == 1


def test_each_block_world_is_built_once_with_feedback_across_blocks(monkeypatch):
    # Requests of one block still complete after the next block has started; their τ must not
    # rebuild their block's world (it did, back and forth, thousands of times).
    # Every world the contention world draws goes through its parts' one draw method.
    import yafs_safetail.edge.world_parts as parts_module

    built: list[str] = []
    original = parts_module.build_world

    def counting(*args, **kwargs):
        built.append(kwargs["phase"])
        return original(*args, **kwargs)

    monkeypatch.setattr(parts_module, "build_world", counting)
    world = ContentionWorld(ContentionConfig(n_requests=3000, users=20, load=0.8, seed=1, queue=True,
                                             block_requests=1000))
    recorder = _TargetRecorder(5, np.random.default_rng(0))
    run_policy(world, recorder)
    assert sorted(built) == ["test:0", "test:1", "test:2", "test:background"]
    assert recorder.targets == {r: pytest.approx(world.target_s(r)) for r in range(3000)}


@pytest.mark.slow  # several seeds of the sweep; test_load_sweep_small_budget runs the entry point
def test_load_sweep_over_seeds(tmp_path):
    common = [sys.executable, str(SWEEP), "--users", "10", "--loads", "0.2,0.8", "--steps-scale", "0.02",
              "--methods", "MinLoad-1,Tied", "--objectives", "target-vector"]
    out = tmp_path / "seeds"
    done = subprocess.run([*common, "--seeds", "3,5", "--workers", "2", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert json.loads((out / "run.json").read_text())["kind"] == "load_sweep_seeds"
    # Each seed's folder is that seed's own sweep, byte for byte.
    single = tmp_path / "single"
    subprocess.run([*common, "--seed", "5", "--out", str(single)], check=True, capture_output=True, timeout=600)
    for name in ("sweep.csv", "sweep_latency.png", "load-0.8/sweep.csv"):
        assert (out / "seed-5" / name).read_bytes() == (single / name).read_bytes(), name
    rows = pd.read_csv(out / "seeds.csv")
    assert list(rows.columns[:3]) == ["seed", "load", "offered_load"] and sorted(set(rows["seed"])) == [3, 5]
    per_seed = rows[rows["seed"] == 5].drop(columns="seed").reset_index(drop=True)
    pd.testing.assert_frame_equal(per_seed, pd.read_csv(single / "sweep.csv"))
    # SEEDS.md counts, per goal, the seeds whose own SWEEP.md says it holds.
    report = (out / "SEEDS.md").read_text()
    for load in ("0.2", "0.8"):
        goal = f"SafeTail p99 <= 1.05x best fixed at load {load}"
        holds = [seed for seed in (3, 5)
                 if f"| {goal} | yes |" in (out / f"seed-{seed}" / "SWEEP.md").read_text()]
        assert f"| {goal} | {len(holds)} of 2 | {', '.join(map(str, holds)) or 'none'} |" in report
    ratios = []
    for seed in (3, 5):
        frame = pd.read_csv(out / f"seed-{seed}" / "sweep.csv")
        at = frame[frame["load"] == 0.8].set_index("method")
        best = at.drop(index=["SafeTail"])["p99_s"]
        ratios.append(at.loc["SafeTail", "p99_s"] / best.min())
        assert f"{ratios[-1]:.2f} ({best.idxmin()}), {at.loc['SafeTail', 'mean_n_selected']:.2f}" in report
    summary = next(line for line in report.splitlines() if line.startswith("| median (min–max) |"))
    assert summary.endswith(f" {np.median(ratios):.2f} ({min(ratios):.2f}–{max(ratios):.2f}) |")
    # A one-seed sweep's folder is not a multi-seed one's, and the other way round.
    for folder, option in ((single, ["--seeds", "3,5"]), (out, ["--seed", "3"])):
        refused = subprocess.run([*common, *option, "--out", str(folder)], capture_output=True, text=True,
                                 timeout=120)
        assert refused.returncode == 2 and "load sweep's folder" in refused.stderr, refused.stderr
    for bad, message in ((["--seeds", "3,3"], "3 is given twice"), (["--seeds", "3", "--seed", "4"], "not allowed")):
        refused = subprocess.run([*common, *bad, "--out", str(tmp_path / "b")], capture_output=True, text=True,
                                 timeout=120)
        assert refused.returncode == 2 and message in refused.stderr and "Traceback" not in refused.stderr
    assert not (tmp_path / "b").exists()


def test_load_sweep_trains_the_original_codes_targets_as_safetail_q(tmp_path):
    out = tmp_path / "sweep"
    done = sweep_here("--users", "10", "--loads", "0.5", "--steps-scale", "0.02", "--methods", "Tied",
                      "--objectives", "q-target", "--seed", "2", "--out", str(out))
    assert done.returncode == 0, done.stderr
    [safetail] = json.loads((out / "run.json").read_text())["safetails"]
    assert (safetail["name"], safetail["learner"], safetail["preset"]) == ("SafeTail-Q", "q-target", "paper")
    assert list(pd.read_csv(out / "sweep.csv")["method"]) == ["SafeTail-Q", "Tied"]
    # Unless told, a sweep trains the two SafeTails every contention measurement was made with.
    assert SweepConfig(base=ContentionConfig(), loads=(0.5,)).objectives == ("target-vector", "value")
