"""The contention engine against hand-computed cases and queueing theory."""

from __future__ import annotations

import math

import numpy as np
import pytest

from yafs_safetail.contention.engine import (
    EngineError,
    EngineSettings,
    FirstReply,
    RequestBlock,
    ServerSpec,
    run_engine,
)
from yafs_safetail.contention.queueing import QUEUEING_CASES, simulate_case


class Fixed:
    """Sends request j to ``plan[j]``; records outcomes."""

    wants_outcomes = True

    def __init__(self, plan, mode="all", delay_s=math.inf):
        self.plan, self.mode, self.delay_s = plan, mode, delay_s
        self.outcomes: list[FirstReply] = []

    def choose(self, request, active_users):
        return self.plan[request]

    def hedge_delay_s(self):
        return self.delay_s

    def completed(self, reply):
        self.outcomes.append(reply)


def engine(work, emit, plan, *, slots=1, speed=(1.0, 1.0, 0.5, 1 / 3), queue=False, cancel=True,
           rtt=0.0, mode="all", delay_s=math.inf, fallback_s=99.0, input_s=None, output_s=None,
           shared=True, background=(), period_s=math.inf):
    """``input_s[j][i]`` and ``output_s[j][i]``: request j's one-way transfer terms to server i,
    one per contention level (the same number for every entry); None: no transfers."""
    n_servers = len(work[0])

    def flat(table):  # [j][i][level] -> [j][i * levels + level]
        return [[t for by_level in row for t in by_level] for row in table]

    no_transfer = [[(0.0,)] * n_servers for _ in work]
    inputs, outputs = flat(input_s or no_transfer), flat(output_s or no_transfer)
    block = RequestBlock(first=0, input_transfer_s=inputs, output_transfer_s=outputs,
                         propagation_s=[[rtt] * n_servers for _ in work], work_s=work)
    settings = EngineSettings(servers=tuple(ServerSpec(slots, speed) for _ in range(n_servers)),
                              contention_levels=len(inputs[0]) // n_servers, queue=queue, cancel=cancel,
                              fallback_latency_s=fallback_s, shared_links=shared,
                              background_period_s=period_s, background=background)
    dispatcher = Fixed(plan, mode, delay_s)
    return run_engine(settings, emit, len(work), lambda _: block, dispatcher), dispatcher


def test_processor_sharing_splits_the_server_equally():
    # A (work 1) alone for 0.5 s, then shares with B (work 1) at half speed until it ends at
    # 1.5 s; B then runs alone for its last 0.5: ends at 2.0 s.
    result, _ = engine([[1.0], [1.0]], [0.0, 0.5], [(0,), (0,)], slots=2)
    assert result.latency_s.tolist() == pytest.approx([1.5, 1.5])
    assert result.busy_s == pytest.approx(1.5 + 1.5)


def test_a_full_server_refuses_and_the_request_falls_back():
    result, outcomes = engine([[1.0], [1.0]], [0.0, 0.5], [(0,), (0,)], slots=1)
    assert result.latency_s.tolist() == [1.0, 99.0]
    assert result.fallback.tolist() == [False, True]
    by_request = {o.request: o for o in outcomes.outcomes}
    assert by_request[1].refused == 1 and by_request[1].winner == -1
    assert [o.request for o in outcomes.outcomes] == [1, 0]  # in completion order


def test_a_fifo_queue_makes_the_copy_wait():
    result, _ = engine([[1.0], [1.0]], [0.0, 0.5], [(0,), (0,)], slots=1, queue=True)
    assert result.latency_s.tolist() == pytest.approx([1.0, 1.5])
    assert not result.fallback.any()


def test_cancellation_stops_the_slower_copy_after_the_propagation():
    work = [[1.0, 3.0]]
    with_cancel, _ = engine(work, [0.0], [(0, 1)], slots=1, rtt=0.1)
    without, _ = engine(work, [0.0], [(0, 1)], slots=1, rtt=0.1, cancel=False)
    # Reply from server 0 at 0.1 + 1 + 0.1; the cancel reaches server 1 0.1 s later.
    assert with_cancel.latency_s[0] == pytest.approx(1.2)
    assert with_cancel.cancelled_copies == 1 and without.cancelled_copies == 0
    assert with_cancel.busy_s == pytest.approx(1.0 + 1.2)
    assert without.busy_s == pytest.approx(1.0 + 3.0)


def test_hedge_sends_the_second_copy_only_when_the_first_is_late():
    work = [[5.0, 0.5], [0.2, 0.5]]
    result, _ = engine(work, [0.0, 10.0], [(0, 1), (0, 1)], slots=1, mode="hedge", delay_s=1.0)
    # Request 0: no reply by 1 s, the hedge to server 1 answers at 1.5 s. Request 1: server 0
    # answers at 0.2 s, before the hedge delay: one copy only.
    assert result.latency_s.tolist() == pytest.approx([1.5, 0.2])
    assert result.n_copies.tolist() == [2, 1]


def test_hedge_goes_at_once_when_the_first_copy_is_refused():
    work = [[4.0, 1.0], [1.0, 0.3]]
    result, _ = engine(work, [0.0, 1.0], [(0,), (0, 1)], slots=1, mode="hedge", delay_s=10.0)
    assert result.latency_s[1] == pytest.approx(0.3)
    assert result.refused.tolist() == [0, 1]


def test_tied_copies_cancel_each_other_once_one_runs():
    work = [[1.0, 0.4]]
    result, _ = engine(work, [0.0], [(0, 1)], slots=1, rtt=0.05, mode="tied")
    # Both start at 0.05; each cancel takes 0.05 s: the first to start (server 0, the first
    # sent) cancels server 1's copy, which therefore never replies.
    assert result.cancelled_copies == 1
    assert result.latency_s[0] == pytest.approx(0.05 + 1.0 + 0.05)
    queued, _ = engine([[1.0, 1.0], [2.0, 0.5]], [0.0, 0.1], [(0,), (0, 1)], slots=1, queue=True,
                       mode="tied")
    # Request 1 waits at server 0 but starts at once on server 1, which cancels the waiting copy.
    assert queued.latency_s[1] == pytest.approx(0.5)
    assert queued.busy_s == pytest.approx(1.0 + 0.5)


def test_unknown_modes_and_unsorted_times_are_refused():
    with pytest.raises(EngineError, match="dispatch mode 'best'"):
        engine([[1.0]], [0.0], [(0,)], mode="best")
    with pytest.raises(EngineError, match="non-decreasing"):
        engine([[1.0], [1.0]], [1.0, 0.5], [(0,), (0,)])


@pytest.mark.parametrize("case", QUEUEING_CASES)
@pytest.mark.parametrize("utilisation", [0.3, 0.6])
def test_matches_mm1_within_two_percent(case, utilisation):
    run = simulate_case(case, n_servers=4, service_rate=1.0, utilisation=utilisation,
                        n_requests=60_000, seed=11)
    assert run.rel_error < 0.02, (run.simulated_mean_s, run.theory_mean_s)


def test_a_wrong_model_would_fail_the_queueing_check():
    # The check can fail: without cancellation, send-to-all is no M/M/1 of rate kμ.
    run = simulate_case("all-cancel", n_servers=4, service_rate=1.0, utilisation=0.3,
                        n_requests=5_000, seed=1)
    assert run.theory_mean_s == pytest.approx(1 / (4 - 1.2))
    assert abs(np.log(run.simulated_mean_s / (1 / (1 - 0.3)))) > 0.5  # far from one M/M/1 at λ/k


def test_hedge_without_a_delay_yet_sends_one_copy_and_ends():
    # Before Hedge has latencies its delay is infinite: one copy, no timer at infinity.
    result, _ = engine([[1.0, 0.1], [1.0, 0.1]], [0.0, 0.5], [(0, 1), (0, 1)], slots=2, mode="hedge",
                       queue=True)
    assert result.latency_s.tolist() == pytest.approx([1.5, 1.5])
    assert result.n_copies.tolist() == [1, 1] and result.end_s < 10


def link_engine(input_s, output_s, emit, plan, *, work=None, **options):
    """Servers with four slots, full speed and two contention levels (``input_s[j][i]`` is a
    pair: the term alone and with one other user); no propagation."""
    work = work or [[0.0] * len(input_s[0]) for _ in input_s]
    return engine(work, emit, plan, slots=4, speed=(1.0,) * 8, input_s=input_s, output_s=output_s,
                  **options)


ALONE_SHARED = (0.5, 1.0)  # a one-way term of 0.5 s alone, 1.0 s with one other user: 1 s or 2 s whole
NOTHING = (0.0, 0.0)


def test_transfers_on_one_link_share_it_for_as_long_as_they_overlap():
    # A alone for 0.5 s does half its 1 s transfer; then both at level 1 (2 s each): A's last half
    # takes 1 s (ends at 1.5) while B does half of its own; B's last half alone: ends at 2.0.
    result, dispatcher = link_engine([[ALONE_SHARED], [ALONE_SHARED]], [[NOTHING], [NOTHING]],
                                     [0.0, 0.5], [(0,), (0,)])
    assert result.latency_s.tolist() == pytest.approx([1.5, 1.5])
    by_request = {o.request: o for o in dispatcher.outcomes}
    assert by_request[0].input_transfer_s == pytest.approx(0.75)  # half the 1.5 s it took
    # Read at the start instead: neither sees the other (B's level counts users at the server,
    # and A is still on its way).
    at_start, _ = link_engine([[ALONE_SHARED], [ALONE_SHARED]], [[NOTHING], [NOTHING]],
                              [0.0, 0.5], [(0,), (0,)], shared=False)
    assert at_start.latency_s.tolist() == pytest.approx([1.0, 1.0])


def test_a_server_s_down_and_up_links_are_apart():
    # A's reply (1 s on the up link, from 0) overlaps B's input (1 s on the down link, from 0.5):
    # neither slows the other.
    result, _ = link_engine([[NOTHING], [ALONE_SHARED]], [[ALONE_SHARED], [NOTHING]],
                            [0.0, 0.5], [(0,), (0,)])
    assert result.latency_s.tolist() == pytest.approx([1.0, 1.0])


def test_background_tenants_count_and_their_change_moves_the_transfer_s_end():
    # A tenant arrives at 0.5: A's last half then runs at level 1 (2 s whole): ends at 1.5.
    result, _ = link_engine([[ALONE_SHARED]], [[NOTHING]], [0.0], [(0,)],
                            background=((0,), (1,), (1,), (1,)), period_s=0.5)
    assert result.latency_s[0] == pytest.approx(1.5)
    # It leaves again at 1.0 (the rows repeat): the last quarter runs alone, 0.25 s.
    back_and_forth, _ = link_engine([[ALONE_SHARED]], [[NOTHING]], [0.0], [(0,)],
                                    background=((0,), (1,)), period_s=0.5)
    assert back_and_forth.latency_s[0] == pytest.approx(1.25)


def test_a_cancelled_transfer_leaves_its_link_to_the_others():
    # Request 0 goes to servers 0 (instant) and 1 (a long input); request 1 shares server 1's
    # down link. Request 0's reply at 0 cancels its copy on server 1 at once (no propagation),
    # so request 1's transfer runs alone: 1 s. Without cancellation it shares the link: 2 s.
    inputs = [[NOTHING, (5.0, 10.0)], [NOTHING, ALONE_SHARED]]
    outputs = [[NOTHING, NOTHING], [NOTHING, NOTHING]]
    result, _ = link_engine(inputs, outputs, [0.0, 0.0], [(0, 1), (1,)])
    kept, _ = link_engine(inputs, outputs, [0.0, 0.0], [(0, 1), (1,)], cancel=False)
    assert result.latency_s[1] == pytest.approx(1.0)
    assert kept.latency_s[1] == pytest.approx(2.0)
    assert result.cancelled_copies == 1


def test_a_reply_still_on_its_up_link_is_cancelled_and_frees_it():
    # Request 0's copy on server 0 answers after 0.2 s of work; its copy on server 1 (no work) is
    # sending a long reply on server 1's up link, shared with request 1's reply; the cancel
    # stops that reply at 0.2, after which request 1's runs alone.
    inputs = [[NOTHING, NOTHING], [NOTHING, NOTHING]]
    outputs = [[NOTHING, (5.0, 10.0)], [NOTHING, ALONE_SHARED]]
    work = [[0.2, 0.0], [0.0, 0.0]]
    result, _ = link_engine(inputs, outputs, [0.0, 0.0], [(0, 1), (1,)], work=work)
    # Request 1: 0.2 s at level 1 (a tenth of its 2 s), then 0.9 of 1 s alone: 1.1 s.
    assert result.latency_s.tolist() == pytest.approx([0.2, 1.1])
    assert result.cancelled_copies == 1
