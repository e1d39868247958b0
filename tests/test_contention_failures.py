"""Failures and time-outs in the contention world: off, nothing moves; on, exactly the copies
a scripted outage reaches are lost, and every request ends for a stated reason."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from contention_helpers import run_hand_made

from yafs_safetail.contention.run import SUMMARY_COLUMNS, run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionError, ContentionWorld
from yafs_safetail.edge.failures import END_REASONS, FailureSettings
from yafs_safetail.methods.registry import make_baseline

FALLBACK_S = 99.0
TIMEOUT_S = 3.0


def engine(work, emit, plan, outages, *, slots=1, rtt=0.1, output_s=0.0, mode="all", delay_s=math.inf,
           cancel=True, timeout_s=TIMEOUT_S, shared=True):
    """Two-or-more-server worlds without contention levels: ``output_s`` is every reply's one-way
    transfer term (its transfer takes twice that), inputs take no time."""
    return run_hand_made(work, emit, plan, outages=outages, slots=slots, speed=(1.0, 1.0, 0.5, 1 / 3), rtt=rtt,
                         output_s=output_s, cancel=cancel, timeout_s=timeout_s, mode=mode, delay_s=delay_s,
                         shared=shared, fallback_latency_s=FALLBACK_S, per_process_w=2.0)


def reasons(result) -> list[str]:
    return [END_REASONS[code] for code in result.end_reason.tolist()]


def test_failures_off_leave_every_result_as_it_was():
    # Pinned on main before failures existed: per-request latency, copies, refusals, fallbacks,
    # winners, server time and cancellations of small runs in both link readings.
    digest = hashlib.sha256()
    for links in ("shared", "at-start"):
        world = ContentionWorld(ContentionConfig(users=5, n_requests=400, seed=2, load=0.8, queue=True,
                                                 links=links, block_requests=200,
                                                 failures=FailureSettings()))
        assert world.timeout_s == math.inf and world.engine_settings().outages == ((),) * 5
        for name in ("Rand-2", "Hedge", "Tied"):
            result = run_policy(world, make_baseline(name, 5, np.random.default_rng(0))).result
            for values in (result.latency_s, result.n_copies, result.refused, result.fallback, result.winner):
                digest.update(np.ascontiguousarray(values).tobytes())
            digest.update(repr((result.busy_s, result.cancelled_copies)).encode())
            assert result.lost.sum() == 0 and set(reasons(result)) <= {"reply", "all_refused"}
    assert digest.hexdigest() == "266392fd1e0e2b303039e7ce3c0294ff7509866b192430d832bd4d17740cdf43"


def test_a_scripted_outage_loses_exactly_the_copies_it_reaches():
    # Two servers, one slot each, ρ = 0.1 s, time-out 3 s, fallback 99 s.
    work = [[1.0, 1.0],   # 0 @0: server 1's copy runs from 0.1 and is lost at 0.5; server 0 replies at 1.2
            [1.0, 1.0],   # 1 @1: only to server 1, down: lost at once -> all_lost at 4
            [1.0, 1.0],   # 2 @4: server 1 is back (up at 3.5): served, 1.2
            [5.0, 1.0],   # 3 @10: server 0 alone, too slow: time-out at 13, cancelled at 13.1
            [5.0, 1.0],   # 4 @20: server 0 busy until the time-out at 23
            [1.0, 1.0],   # 5 @20.5: server 0 refuses, server 1 is down (20..30) -> all_lost at 23.5
            [1.0, 1.0]]   # 6 @40: in flight when server 0 fails for 30 ms (40.05..40.08): lost
    emit = [0.0, 1.0, 4.0, 10.0, 20.0, 20.5, 40.0]
    plan = [(0, 1), (1,), (1,), (0,), (0,), (0, 1), (0,)]
    outages = (((40.05, 40.08),), ((0.5, 3.5), (20.0, 30.0)))
    result, dispatcher = engine(work, emit, plan, outages)
    timeout_latency = TIMEOUT_S + FALLBACK_S
    assert reasons(result) == ["reply", "all_lost", "reply", "timeout", "timeout", "all_lost", "all_lost"]
    assert result.latency_s.tolist() == pytest.approx(
        [1.2, timeout_latency, 1.2, timeout_latency, timeout_latency, timeout_latency, timeout_latency])
    assert result.lost.tolist() == [1, 1, 0, 0, 0, 1, 1]
    assert result.refused.tolist() == [0, 0, 0, 0, 0, 1, 0]
    assert result.fallback.tolist() == [False, True, False, True, True, True, True]
    # The time-out cancels the copy still running (request 3 ran 10.1..13.1 of its 5 s).
    assert result.cancelled_copies == 2
    # Server energy (2 W per copy): request 0: 1 s on server 0 + 0.4 s on server 1 until it failed.
    assert result.server_energy_j[0] == pytest.approx(2.0 * 1.4)
    assert result.saved_energy_j[3] == pytest.approx(2.0 * 2.0)
    # The feedback carries the same reason and the copies lost by then.
    assert dispatcher.outcomes[1].end_reason == "all_lost" and dispatcher.outcomes[1].lost == 1
    assert dispatcher.outcomes[0].end_reason == "reply" and dispatcher.outcomes[0].winner == 0

    # A reply on the shared up link (0.5 s each way, 1 s on the link, 51.1..52.1) when its
    # server fails: lost; a reply already past the link (in ρ) when its server fails: not.
    on_link, _ = engine([[1.0, 1.0]], [50.0], [(0,)], ((((51.5, 51.6),), ())), output_s=0.5)
    past_link, _ = engine([[1.0, 1.0]], [60.0], [(0,)], ((((62.15, 62.2),), ())), output_s=0.5)
    assert reasons(on_link) == ["all_lost"] and on_link.lost.tolist() == [1]
    assert reasons(past_link) == ["reply"] and past_link.latency_s[0] == pytest.approx(2.2)


@pytest.mark.parametrize("shared", [True, False])
def test_at_start_links_lose_a_reply_still_on_its_link(shared):
    # Reply transfer 61.1..62.1 (twice the 0.5 s term), then ρ: a failure at 61.5 loses it in
    # both link readings.
    result, _ = engine([[1.0, 1.0]], [60.0], [(0,)], (((61.5, 61.6),), ()), output_s=0.5, shared=shared)
    assert reasons(result) == ["all_lost"] and result.lost.tolist() == [1]


def test_hedged_and_tied_dispatch_survive_a_failed_server():
    down_1 = ((), ((0.0, 100.0),))
    # Hedge: the first copy goes to the down server (lost, unknown to the user); the timer
    # sends the next at 0.5, which answers at 0.5 + 1.2.
    hedged, _ = engine([[1.0, 1.0]], [0.0], [(1, 0)], down_1, mode="hedge", delay_s=0.5)
    assert reasons(hedged) == ["reply"] and hedged.latency_s[0] == pytest.approx(1.7)
    assert hedged.lost.tolist() == [1] and hedged.n_copies.tolist() == [2]
    # Without a timer the next copy would go only on a refusal: the user waits for the time-out.
    waiting, _ = engine([[1.0, 1.0]], [0.0], [(1, 0)], down_1, mode="hedge")
    assert reasons(waiting) == ["all_lost"] and waiting.n_copies.tolist() == [1]
    # Tied: the copy that starts first (server 1's) cancels its sibling, then its server fails:
    # no copy answers, and not every copy was lost (one was cancelled).
    tied, _ = engine([[1.0, 1.0]], [0.0], [(1, 0)], ((), ((0.5, 1.0),)), mode="tied")
    assert reasons(tied) == ["timeout"] and tied.latency_s[0] == pytest.approx(TIMEOUT_S + FALLBACK_S)
    assert tied.lost.tolist() == [1] and tied.cancelled_copies == 1
    # Tied with the sibling on a down server: the live copy answers.
    live, _ = engine([[1.0, 1.0]], [0.0], [(1, 0)], down_1, mode="tied")
    assert reasons(live) == ["reply"] and live.latency_s[0] == pytest.approx(1.2)
    # A hedge timer of a request that already ended does nothing.
    early, _ = engine([[0.2, 1.0]], [0.0], [(0, 1)], down_1, mode="hedge", delay_s=1.0)
    assert early.n_copies.tolist() == [1] and reasons(early) == ["reply"]


@pytest.fixture(scope="module")
def failing_world() -> ContentionWorld:
    return ContentionWorld(ContentionConfig(users=10, n_requests=1500, seed=3, load=0.1, block_requests=500,
                                            failures=FailureSettings.for_unavailability(0.3, mttr_s=5.0)))


def test_a_world_with_failures_draws_them_from_their_own_stream(failing_world):
    plain = ContentionWorld(ContentionConfig(users=10, n_requests=1500, seed=3, load=0.1, block_requests=500))
    assert np.array_equal(plain.emit_s, failing_world.emit_s)
    assert plain.block(0) == failing_world.block(0)
    assert plain.engine_settings().background == failing_world.engine_settings().background
    # The time-out is the worst-case live copy's latency, finite, and beyond every one-copy
    # Eq. 1 latency of the block.
    assert failing_world.timeout_s == failing_world.worst_case_copy_latency_s < math.inf
    down = failing_world.down_intervals
    assert all(down.starts_s[i] for i in range(failing_world.n_servers))
    again = ContentionWorld(failing_world.config)
    assert again.down_intervals == down


def test_failures_cost_successes_and_redundancy_buys_them_back(failing_world):
    rows = {}
    for name in ("Rand-1", "Rand-3", "Hedge", "Tied", "Oracle"):
        run = run_policy(failing_world, make_baseline(name, 5, np.random.default_rng(0)))
        row = summarise(run)
        assert list(row) == list(SUMMARY_COLUMNS)
        shares = row["success_rate"] + row["share_all_lost"] + row["share_timeout"] + row["share_all_refused"]
        assert shares == pytest.approx(1.0)
        result = run.result
        ended = result.end_reason != 0
        assert np.array_equal(ended, result.fallback)
        assert np.all(result.latency_s[result.end_reason >= 2] >= failing_world.timeout_s)
        rows[name] = row
    # At a light load (few refusals) more copies survive more outages.
    assert rows["Rand-1"]["share_all_lost"] > 0.2
    assert rows["Rand-3"]["success_rate"] > rows["Rand-1"]["success_rate"] + 0.1
    assert rows["Oracle"]["success_rate"] > rows["Rand-3"]["success_rate"]
    assert rows["Oracle"]["energy_j_per_request"] > rows["Rand-1"]["energy_j_per_request"]


def test_bad_failure_settings_are_one_line_errors():
    with pytest.raises(ContentionError, match="failures"):
        ContentionWorld(ContentionConfig(failures="often"))  # type: ignore[arg-type]
    with pytest.raises(ContentionError, match="energy"):
        ContentionWorld(ContentionConfig(energy=None))  # type: ignore[arg-type]


def test_outages_without_a_time_out_are_refused():
    from yafs_safetail.contention.engine import EngineError

    with pytest.raises(EngineError, match="timeout_s"):
        engine([[1.0, 1.0]], [0.0], [(0,)], (((0.5, 1.0),), ()), timeout_s=math.inf)
