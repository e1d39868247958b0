"""Drawing a phase's world: :func:`build_world` assembles an :class:`EdgeWorld` from its draws
(``edge.sampling``) and inputs (``edge.inputs``), stream by stream (:data:`PHASE_STREAMS`).

:class:`EdgeWorld` itself, what it holds and how it is read, lives in ``edge.phase_world``;
it and the input helpers are importable from here too (the examples and most callers take
``build_world`` and ``EdgeWorld`` together from this module).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from yafs_safetail.defaults import DEFAULT_STEP_INTERVAL_S
from yafs_safetail.edge import calibration, sampling
from yafs_safetail.edge.calibration import LANDED, WorldSettings
from yafs_safetail.edge.energy import EnergyModel
from yafs_safetail.edge.failures import (
    DownIntervals,
    FailureSettings,
    effective_timeout_s,
    phase_down_intervals,
)
from yafs_safetail.edge.inputs import (
    TraceInputs,
    WorldError,
    load_inputs,
    trace_inputs,
    worst_case_copy_latency_s,
)
from yafs_safetail.edge.latency import (
    input_bottleneck_bps,
    output_bottleneck_bps,
    target_latency_s,
    transfer_s,
)
from yafs_safetail.edge.movement import MobilityPlan, Movement, draw_movement
from yafs_safetail.edge.phase_world import (
    EdgeWorld,
    HopTables,
    cpu_utilisation,
    memory_utilisation,
)
from yafs_safetail.edge.sampling import link_scales, phase_seed_sequence
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.usecases import UseCase

__all__ = [
    "DEFAULT_EPISODE_STEPS", "DEFAULT_MAX_LOAD", "EdgeWorld", "HopTables", "TraceInputs",
    "WorldError", "build_world", "cpu_utilisation", "link_scales", "load_inputs",
    "memory_utilisation", "phase_seed_sequence", "phase_streams", "target_compute_by_request_s",
    "trace_inputs", "worst_case_copy_latency_s", "PHASE_STREAMS",
]

#: A phase's independent random streams, in the order they are spawned from the phase's seed
#: (:func:`phase_streams`). The order decides every draw of every world: never reorder it, and
#: add a new stream only at the end.
PHASE_STREAMS: tuple[str, ...] = ("requests", "user_bandwidth", "episodes", "servers", "failures", "mobility")


def phase_streams(seed: int, phase: str) -> dict[str, np.random.SeedSequence]:
    """The seed of each of a phase's streams (:data:`PHASE_STREAMS`), by name.

    Another world drawing a quantity exactly as :func:`build_world` does (the contention
    world's per-user RTTs) takes the same stream by its name.
    """
    spawned = phase_seed_sequence(seed, phase).spawn(len(PHASE_STREAMS))
    return dict(zip(PHASE_STREAMS, spawned, strict=True))


#: Paper Table I: maximum load of each edge server.
DEFAULT_MAX_LOAD = 4
#: Paper Table I: α_s, steps per episode.
DEFAULT_EPISODE_STEPS = 256


def target_compute_by_request_s(inputs: TraceInputs, gamma: np.ndarray, nu: int,
                                reading: str) -> np.ndarray:
    """C(s_j) of Eq. 4 for every request: the median compute time at ν parallel instances.

    ``"trace_median"``: the compute trace's median at ν, the same for every request.
    ``"request"``: the median for *this* request's input: the trace's median at ν times the
    compute model's prediction for the request's Γ_j at ν over the model's median prediction
    for the trace's own inputs (the model's Gaussian noise is centred on its prediction, so the
    prediction is the request's median; the ratio keeps the measured median as the anchor).
    Where Γ holds nothing but the number of processes (use case 1) every input is alike and
    both readings give the trace's median.

    Args:
        inputs: the traces and compute model.
        gamma: Γ per request, shape (n_requests, g).
        nu: ν.
        reading: ``WorldSettings.target_compute``.

    Returns:
        Seconds per request, shape (n_requests,).
    """
    trace_median_s = float(inputs.median_compute_by_k_s[nu - 1])
    n_requests = gamma.shape[0]
    if reading == "trace_median" or gamma.shape[1] == 0:
        return np.full(n_requests, trace_median_s)
    trace_gamma = inputs.request_gamma
    median_prediction_s = float(np.median(
        inputs.predict_compute_s(trace_gamma, np.full(trace_gamma.shape[0], nu))))
    prediction_s = inputs.predict_compute_s(gamma, np.full(n_requests, nu))
    return trace_median_s * np.asarray(prediction_s, dtype=float) / median_prediction_s


def _check_world_inputs(scenario: EdgeScenario, use_case: UseCase, inputs: TraceInputs,
                        n_steps: int, episode_steps: int, max_load: int, nu: int) -> None:
    """Raises :class:`WorldError` (one line naming the input) where these cannot make a world."""
    if n_steps < 1 or episode_steps < 1:
        raise WorldError(f"n_steps and episode_steps must be >= 1, got {n_steps}, {episode_steps}")
    if not 1 <= max_load <= inputs.max_processes:
        raise WorldError(
            f"max_load: {max_load} needs compute times for k = 1..{max_load} processes but "
            f"{inputs.source} covers k = 1..{inputs.max_processes}"
        )
    if nu > inputs.max_processes:
        raise WorldError(f"use case {use_case.number}: ν = {nu} beyond the compute trace")
    missing = [c for c in scenario.server_conditions if c not in inputs.rtt_pools_s]
    if missing:
        raise WorldError(f"{scenario.topology.source}: conditions {missing} have no RTT pool")
    minutes = int(inputs.load_users.shape[0])
    if minutes < episode_steps:
        # An episode reads one load-trace minute per step; a shorter trace would repeat itself
        # within every episode.
        raise WorldError(f"{Path(inputs.source) / 'load.csv'}: rows: {minutes} minutes, but an episode "
                         f"(α_s) needs at least {episode_steps}")
    n_devices = inputs.n_load_devices
    if max(scenario.server_load_devices) >= n_devices:
        raise WorldError(f"{scenario.topology.source}: load device beyond the trace's {n_devices}")


def _worst_copy_latency_s(use_case: UseCase, inputs: TraceInputs, scales: sampling.LinkScales,
                          max_load: int) -> float:
    """The slowest latency an admitted copy can have in this topology (slowest links, longest
    RTT, slowest compute): the fallback's floor and the default time-out with failures on."""
    return worst_case_copy_latency_s(
        inputs, use_case, max_load,
        bandwidth_scale=min(float(scales.server_bandwidth.min()), scales.user_bandwidth),
        extra_propagation_s=float(scales.server_extra_propagation_s.max()),
    )


def _fallback_latency_s(use_case: UseCase, inputs: TraceInputs, settings: WorldSettings,
                        worst_copy_latency_s: float) -> float:
    """The on-device fallback latency of a world.

    With the landed fallback rule it is the use case's, raised to the worst-case edge latency of
    this topology if that is higher, so a fallback is never faster than an edge reply and Oracle
    stays a per-request lower bound. With a calibrated rule it is a multiple of the use case's
    median one-process compute time (assumption iv: the on-device version's run time); then a
    method whose chosen servers all refuse may beat Oracle on that request, when Oracle's
    admitted copies are slower than the device.
    """
    if settings.fallback_compute_multiple is None:
        # Rounded up to 0.1 s so the recorded value reads cleanly in results.
        return max(float(use_case.fallback_latency_s), math.ceil(worst_copy_latency_s * 10) / 10)
    return settings.fallback_compute_multiple * float(inputs.median_compute_by_k_s[0])


def build_world(
    scenario: EdgeScenario,
    use_case: UseCase,
    inputs: TraceInputs,
    n_steps: int,
    seed: int,
    phase: str,
    episode_steps: int = DEFAULT_EPISODE_STEPS,
    max_load: int = DEFAULT_MAX_LOAD,
    settings: WorldSettings = LANDED,
    failures: FailureSettings | None = None,
    energy: EnergyModel | None = None,
    step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
    mobility: MobilityPlan | None = None,
) -> EdgeWorld:
    """Draws a phase's world.

    Args:
        scenario: the topology and placement (server conditions and load devices).
        use_case: the use case (:class:`yafs_safetail.edge.usecases.UseCase`).
        inputs: the loaded traces and compute model.
        n_steps: number of requests (one per step).
        seed: the run's seed.
        phase: the phase name (independent streams per phase).
        episode_steps: α_s; the load trace restarts at a random row at every episode start.
        max_load: the server load limit.
        settings: the readings and calibrated parameters (:mod:`yafs_safetail.edge.calibration`):
            propagation per direction, load scaling and start rows, bandwidth sharing, the
            fallback rule and ν.
        failures: which servers fail and the user's time-out (``edge.failures``; None: no
            server ever fails, no time-out, every draw and latency as without this argument).
        energy: the servers' and the device's power models (None: ``EnergyModel()``).
        step_interval_s: time between two requests; the outages are drawn over the phase's
            ``n_steps + 1`` intervals (the last request's copies end within the interval after it).
        mobility: how the user moves (``edge.movement``; None: the user stays where the
            topology puts it and every link keeps the topology's condition, as without this
            argument).

    The link BW and PR of the topology act on the trace pools (:func:`link_scales`); the
    fallback latency follows the settings' rule (:func:`_fallback_latency_s`).

    Raises:
        WorldError: inconsistent sizes or parameters.
    """
    # Long only by EdgeWorld's 27 named fields: every draw of a phase, in stream order, in one place.
    nu = use_case.nu if settings.nu is None else settings.nu
    _check_world_inputs(scenario, use_case, inputs, n_steps, episode_steps, max_load, nu)
    scales = link_scales(scenario)
    failures = FailureSettings() if failures is None else failures
    # The bound costs a compute-model pass: computed once, and only when the landed fallback rule
    # or the default time-out with failures on needs it.
    needs_bound = settings.fallback_compute_multiple is None or (failures.enabled and failures.timeout_s is None)
    worst_s = _worst_copy_latency_s(use_case, inputs, scales, max_load) if needs_bound else math.inf
    fallback_latency_s = _fallback_latency_s(use_case, inputs, settings, worst_s)

    n = scenario.n_servers
    streams = phase_streams(seed, phase)
    request_seq, user_bw_seq = streams["requests"], streams["user_bandwidth"]
    episode_seq, servers_seq = streams["episodes"], streams["servers"]
    servers = sampling.draw_servers(servers_seq, n, n_steps)
    requests = sampling.draw_requests(np.random.default_rng(request_seq), inputs, use_case, n_steps)
    user_uplink_bps, user_downlink_bps = sampling.draw_user_bandwidth(
        np.random.default_rng(user_bw_seq), inputs, scales.user_bandwidth, n_steps)
    load_row, background = sampling.draw_background_load(
        episode_seq, calibration.load_levels(inputs.load_users, settings.load_peak_users, max_load),
        np.asarray(scenario.server_load_devices), n_steps, episode_steps,
        per_server=settings.load_start == "per_server")
    uplink, downlink = sampling.bandwidth_by_level(
        inputs, servers.bandwidth_quantiles, scales.server_bandwidth, settings.bandwidth_share_exponent)
    rtt_s, median_propagation_s = sampling.propagation(
        inputs, scenario.server_conditions, servers.rtt_quantiles,
        scales.server_extra_propagation_s, settings.propagation_rtt_fraction)
    movement: Movement | None = None
    step_median_propagation_s = median_propagation_s[None, :]
    if mobility is not None:
        # Drawn from its own stream, after the others: every other draw stays as without it.
        rtt_s, movement = draw_movement(
            mobility, scenario, inputs, servers.rtt_quantiles, scales.server_extra_propagation_s,
            settings.propagation_rtt_fraction, step_interval_s, np.random.default_rng(streams["mobility"]))
        step_median_propagation_s = movement.median_propagation_s
    target_compute_s = target_compute_by_request_s(inputs, requests.gamma, nu, settings.target_compute)
    # The outages are drawn last, from their own stream: a world without failures draws nothing
    # here, and a world with them has exactly the same requests, bandwidths, loads and RTTs.
    down_intervals: DownIntervals | None = (
        phase_down_intervals(failures, n, (n_steps + 1) * step_interval_s,
                             np.random.default_rng(streams["failures"]))
        if failures.enabled else None)
    return EdgeWorld(
        seed=int(seed),
        phase=phase,
        scenario=scenario,
        use_case=use_case,
        max_load=max_load,
        episode_steps=episode_steps,
        request_row=requests.rows,
        input_bytes=requests.input_bytes,
        output_bytes=requests.output_bytes,
        est_output_bytes=requests.est_output_bytes,
        gamma=requests.gamma,
        user_uplink_bps=user_uplink_bps,
        user_downlink_bps=user_downlink_bps,
        load_row=load_row,
        background_users=background,
        rtt_s=rtt_s,
        median_propagation_s=median_propagation_s,
        server_uplink_by_level_bps=uplink,
        server_downlink_by_level_bps=downlink,
        input_transfer_by_level_s=transfer_s(
            requests.input_bytes[:, None, None],
            input_bottleneck_bps(downlink, user_uplink_bps[:, None, None])),
        output_transfer_by_level_s=transfer_s(
            requests.output_bytes[:, None, None],
            output_bottleneck_bps(uplink, user_downlink_bps[:, None, None])),
        compute_by_processes_s=sampling.compute_by_processes(inputs, requests.gamma, servers.noise, max_load),
        target_compute_s=target_compute_s,
        target_s=np.asarray(target_latency_s(
            requests.input_bytes, requests.est_output_bytes, user_uplink_bps, user_downlink_bps,
            step_median_propagation_s, target_compute_s), dtype=float)
        if settings.target_latency_s is None else np.full(n_steps, settings.target_latency_s),
        fallback_latency_s=fallback_latency_s,
        nu=nu,
        settings=settings,
        failures=failures,
        down_intervals=down_intervals,
        timeout_s=effective_timeout_s(failures, worst_s),
        energy=EnergyModel() if energy is None else energy,
        movement=movement,
    )
