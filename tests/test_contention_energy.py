"""Energy in the contention world: every copy's joules add up to each server's and each
device's, and a cancelled copy saves exactly its unspent compute × the per-process power."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contention_helpers import RADIO, run_hand_made

from yafs_safetail.contention.run import run_policy
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.edge.energy import EnergyModel, ServerPowerModel
from yafs_safetail.edge.failures import FailureSettings
from yafs_safetail.methods.registry import make_baseline

PER_PROCESS_W = 2.5


def engine(work, emit, plan, *, slots=2, speed=(1.0, 1.0, 0.5, 1 / 3, 0.25), rtt=0.1, input_s=0.0,
           output_s=0.0, input_bytes=0.0, output_bytes=0.0, cancel=True, queue=False, outages=(),
           timeout_s=math.inf, mode="all", delay_s=math.inf, shared=True):
    return run_hand_made(work, emit, plan, outages=outages, slots=slots, speed=speed, rtt=rtt, input_s=input_s,
                         output_s=output_s, input_bytes=input_bytes, output_bytes=output_bytes, cancel=cancel,
                         queue=queue, timeout_s=timeout_s, mode=mode, delay_s=delay_s, shared=shared,
                         fallback_latency_s=9.0, per_process_w=PER_PROCESS_W, radio=RADIO)


def test_a_copy_is_charged_its_residence_time_under_processor_sharing():
    # A (work 1) alone for 0.5 s, then with B at half speed until 1.5 s; B alone to 2.0 s:
    # each computed 1.5 s, and the server ran 1 job, then 2, then 1: ∫ n dt = 3 s.
    result, _ = engine([[1.0], [1.0]], [0.0, 0.5], [(0,), (0,)], rtt=0.0)
    assert result.server_energy_j.tolist() == pytest.approx([PER_PROCESS_W * 1.5] * 2)
    assert result.server_active_s.tolist() == pytest.approx([3.0])


def test_a_cancelled_copy_saves_its_unspent_compute_at_its_servers_one_job_speed():
    # Server speed 0.5 (an IPT half the reference's): work 1 takes 2 s, work 3 takes 6 s. The
    # reply from server 0 comes at 0.1 + 2 + 0.1; the cancel reaches server 1 at 2.3, where the
    # copy ran 2.2 s (1.1 of its 3 s of work): 1.9 s of work left = 3.8 s at speed 0.5.
    slow = (0.5, 0.5, 0.25, 0.5 / 3)
    result, dispatcher = engine([[1.0, 3.0]], [0.0], [(0, 1)], slots=1, speed=slow)
    assert result.latency_s[0] == pytest.approx(2.2)
    assert result.server_energy_j[0] == pytest.approx(PER_PROCESS_W * (2.0 + 2.2))
    assert result.saved_energy_j[0] == pytest.approx(PER_PROCESS_W * 3.8)
    # Spent + saved = the whole compute of both copies, alone on their servers.
    assert result.server_energy_j[0] + result.saved_energy_j[0] == pytest.approx(PER_PROCESS_W * (2.0 + 6.0))
    # The feedback comes at the reply: server 1's copy had run 2.1 s by then, nothing saved yet.
    outcome = dispatcher.outcomes[0]
    assert outcome.server_energy_j == pytest.approx(PER_PROCESS_W * (2.0 + 2.1))
    assert outcome.saved_energy_j == 0.0
    # A copy cancelled while it waits in the queue saves all of its work.
    queued, _ = engine([[1.0, 5.0], [1.0, 2.0]], [0.0, 0.0], [(1,), (0, 1)], slots=1, queue=True)
    assert queued.saved_energy_j[1] == pytest.approx(PER_PROCESS_W * 2.0)


def test_radio_energy_is_every_upload_and_every_reply_received():
    # Two copies per request, 0.2 s input and 0.3 s output terms (transfers of 0.4 s and 0.6 s),
    # requests far apart, no cancellation: the device sends 2 inputs and receives 2 replies.
    input_bytes, output_bytes = 40_000.0, 2_000.0
    result, _ = engine([[1.0, 1.5]] * 3, [0.0, 10.0, 20.0], [(0, 1)] * 3, input_s=0.2, output_s=0.3,
                       input_bytes=input_bytes, output_bytes=output_bytes, cancel=False)
    one_request_j = 2 * (RADIO.upload_energy_j(input_bytes, 0.4) + RADIO.download_energy_j(output_bytes, 0.6))
    assert result.radio_energy_j.tolist() == pytest.approx([one_request_j] * 3, rel=1e-12)
    # With cancellation the loser's reply is never sent (cancelled at 2.3 while it computes).
    cancelled, _ = engine([[1.0, 2.5]], [0.0], [(0, 1)], input_s=0.2, output_s=0.3,
                          input_bytes=input_bytes, output_bytes=output_bytes)
    assert cancelled.radio_energy_j[0] == pytest.approx(
        2 * RADIO.upload_energy_j(input_bytes, 0.4) + RADIO.download_energy_j(output_bytes, 0.6))
    # A reply cancelled on its link (2.0..2.6, cancel at 2.3) was half received: half its bytes
    # and its 0.3 s on the air.
    half, _ = engine([[1.0, 1.5]], [0.0], [(0, 1)], input_s=0.2, output_s=0.3,
                     input_bytes=input_bytes, output_bytes=output_bytes)
    assert half.radio_energy_j[0] == pytest.approx(
        2 * RADIO.upload_energy_j(input_bytes, 0.4) + RADIO.download_energy_j(output_bytes, 0.6)
        + RADIO.download_energy_j(output_bytes / 2, 0.3))


@pytest.mark.parametrize("links", ["shared", "at-start"])
def test_every_copy_adds_up_to_each_servers_and_each_devices_energy(links):
    # A busy world with failures, queueing off and on, cancellation: per-request server energy
    # sums to the servers' ∫ per-process power × copies computing dt, kept apart in the loop.
    for queue in (False, True):
        world = ContentionWorld(ContentionConfig(
            users=8, n_requests=800, seed=6, load=0.7, queue=queue, links=links, block_requests=400,
            failures=FailureSettings.for_unavailability(0.2, mttr_s=5.0),
            energy=EnergyModel(server=ServerPowerModel(idle_w=5.0, max_w=45.0))))
        for name in ("Rand-3", "Hedge", "Tied"):
            result = run_policy(world, make_baseline(name, 5, np.random.default_rng(2))).result
            per_process_w = world.config.energy.server.per_process_w
            assert per_process_w == 10.0
            server_total_j = per_process_w * float(np.sum(result.server_active_s))
            assert float(np.sum(result.server_energy_j)) == pytest.approx(server_total_j, rel=1e-12, abs=1e-9)
            assert per_process_w * result.busy_s == pytest.approx(server_total_j, rel=1e-12, abs=1e-9)
            assert result.lost_copies == int(result.lost.sum()) > 0
            # Each device's radio energy is the sum over its requests; every request sent at
            # least one copy, so each device with requests spent some.
            per_device_j = np.bincount(world.user, weights=result.radio_energy_j, minlength=8)
            assert per_device_j.sum() == pytest.approx(result.radio_energy_j.sum(), rel=1e-12)
            assert np.all(per_device_j[np.bincount(world.user, minlength=8) > 0] > 0)
            assert np.all(result.saved_energy_j >= 0) and np.all(result.energy_j > 0)


def test_the_servers_energy_matches_to_the_nanojoule_on_a_hand_made_world():
    rng = np.random.default_rng(11)
    n = 60
    work = rng.uniform(0.2, 2.0, size=(n, 3)).tolist()
    emit = np.cumsum(rng.exponential(0.3, size=n)).tolist()
    plan = [tuple(sorted(rng.choice(3, size=int(rng.integers(1, 4)), replace=False).tolist())) for _ in range(n)]
    outages = (((3.0, 4.0),), ((6.0, 9.5),), ())
    for queue in (False, True):
        result, _ = engine(work, emit, plan, slots=2, queue=queue, outages=outages, timeout_s=6.0,
                           input_s=0.05, output_s=0.05, input_bytes=1e4, output_bytes=1e3)
        assert abs(float(np.sum(result.server_energy_j))
                   - PER_PROCESS_W * float(np.sum(result.server_active_s))) < 1e-9
        assert result.lost.sum() > 0 and result.cancelled_copies > 0
