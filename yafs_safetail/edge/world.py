"""The pre-drawn world of a phase, assembled from its draws (``edge.sampling``) and inputs
(``edge.inputs``).

Every method evaluated on a phase runs its own simulation over the same :class:`EdgeWorld`, so
a copy of step *t*'s request sent to server *i* has the same latency whichever subset it was
part of (common random numbers), and, in the landed world, Oracle (all servers) is a
per-request lower bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from yafs_safetail.edge import calibration, published, sampling
from yafs_safetail.edge.calibration import LANDED, WorldSettings
from yafs_safetail.edge.inputs import (
    TraceInputs,
    WorldError,
    load_inputs,
    trace_inputs,
    worst_case_copy_latency_s,
)
from yafs_safetail.edge.latency import (
    CopyLatency,
    copy_latency,
    copy_latency_s,
    input_bottleneck_bps,
    output_bottleneck_bps,
    target_latency_s,
    transfer_s,
)
from yafs_safetail.edge.observation import Observation
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
PHASE_STREAMS: tuple[str, ...] = ("requests", "user_bandwidth", "episodes", "servers")


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


# Utilisation as a function of the number of processes k on a server, from the published
# profiling of one 16 GB, 16-vCPU server (published.py): the server's memory in use grows
# from 829 MB (k = 1) to 853 MB (k = 5), linearly in between; each process gets a CPU share
# of 779/740/531/399/319 % of one vCPU. Utilisation = in use / capacity, capped at 1.
# An idle server (k = 0) counts as 0 for both.
SERVER_MEMORY_MB = 16 * 1024
SERVER_CPU_PERCENT = 16 * 100
_MEMORY_IN_USE_MB = np.concatenate(
    [[0.0], np.linspace(*published.MEMORY_MB_RANGE, published.MAX_PROCESSES)]
)
_CPU_IN_USE_PERCENT = np.concatenate(
    [[0.0], np.arange(1, published.MAX_PROCESSES + 1) * np.asarray(published.CPU_PERCENT_PER_PROCESS)]
)


def memory_utilisation(n_processes: np.ndarray | int) -> np.ndarray:
    """M_i for k = 0..5 processes."""
    return np.minimum(_MEMORY_IN_USE_MB[np.asarray(n_processes)] / SERVER_MEMORY_MB, 1.0)


def cpu_utilisation(n_processes: np.ndarray | int) -> np.ndarray:
    """U_i for k = 0..5 processes: k · CPU share per process / 1600 %, capped at 1."""
    return np.minimum(_CPU_IN_USE_PERCENT[np.asarray(n_processes)] / SERVER_CPU_PERCENT, 1.0)


_MEMORY_UTIL = memory_utilisation(np.arange(published.MAX_PROCESSES + 1))
_CPU_UTIL = cpu_utilisation(np.arange(published.MAX_PROCESSES + 1))


@dataclass(frozen=True)
class HopTables:
    """A world's arrays read on every copy, as nested Python lists.

    Indexing a list is several times faster than indexing a NumPy array with scalars, and the
    values are the same floats. The last two axes of the (step, server, level) and (step,
    server, k - 1) arrays are flattened: entry ``[step][server * width + j]``.

    Attributes:
        background_users: b_i per [step][server].
        rtt_s: ρ_i per [step][server].
        input_transfer_s: per [step][server * levels + level].
        output_transfer_s: per [step][server * levels + level].
        compute_s: per [step][server * max_load + k - 1].
        target_s: τ per [step].
    """

    background_users: list[list[int]]
    rtt_s: list[list[float]]
    input_transfer_s: list[list[float]]
    output_transfer_s: list[list[float]]
    compute_s: list[list[float]]
    target_s: list[float]


@dataclass(frozen=True)
class EdgeWorld:
    """All pre-drawn quantities of one phase (read-only; share it between methods).

    Per-step arrays have shape (n_steps,), per-(step, server) arrays (n_steps, n_servers).

    Attributes:
        seed: the run's seed.
        phase: the phase name.
        scenario: topology + placement.
        use_case: the use case (see :mod:`yafs_safetail.edge.usecases`).
        max_load: a server with this many active users refuses new copies.
        episode_steps: α_s; the load trace restarts at a random row every episode.
        request_row: the compute-trace row each step's request copies its input from.
        input_bytes: Size(I) per step.
        output_bytes: actual Size(O) per step.
        est_output_bytes: eSize(O) per step.
        gamma: Γ per step, shape (n_steps, g).
        user_uplink_bps: Λ^u per step.
        user_downlink_bps: Λ^d per step.
        load_row: the load-trace minute each step reads.
        background_users: b_i per (step, server).
        rtt_s: ρ_i per (step, server), charged on the way in and on the way out.
        median_propagation_s: ρ^μ_i per server (median of its condition's pool).
        server_uplink_by_level_bps: λ^u_i per (step, server, contention level).
        server_downlink_by_level_bps: λ^d_i per (step, server, contention level).
        input_transfer_by_level_s: Size(I)/min(λ^d_i, Λ^u), one of Eq. 1's two equal input
            transfer terms, per (step, server, contention level).
        output_transfer_by_level_s: Size(O)/min(λ^u_i, Λ^d), likewise for the output.
        compute_by_processes_s: compute time per (step, server, k - 1) for k = 1..max_load.
        target_compute_s: C(s_j) of Eq. 4 per step (``settings.target_compute``): the trace's
            median at ν, or that median scaled to the step's own input.
        target_s: τ per step (Eq. 4).
        fallback_latency_s: the on-device fallback latency (assumption iv).
        nu: ν of Eq. 4 used for ``target_s``.
        settings: the world settings it was drawn with.
    """

    seed: int
    phase: str
    scenario: EdgeScenario
    use_case: UseCase
    max_load: int
    episode_steps: int
    request_row: np.ndarray
    input_bytes: np.ndarray
    output_bytes: np.ndarray
    est_output_bytes: np.ndarray
    gamma: np.ndarray
    user_uplink_bps: np.ndarray
    user_downlink_bps: np.ndarray
    load_row: np.ndarray
    background_users: np.ndarray
    rtt_s: np.ndarray
    median_propagation_s: np.ndarray
    server_uplink_by_level_bps: np.ndarray
    server_downlink_by_level_bps: np.ndarray
    input_transfer_by_level_s: np.ndarray
    output_transfer_by_level_s: np.ndarray
    compute_by_processes_s: np.ndarray
    target_compute_s: np.ndarray
    target_s: np.ndarray
    fallback_latency_s: float
    nu: int
    settings: WorldSettings

    @property
    def n_steps(self) -> int:
        return int(self.input_bytes.shape[0])

    @property
    def n_servers(self) -> int:
        return int(self.background_users.shape[1])

    @property
    def n_contention_levels(self) -> int:
        return int(self.server_uplink_by_level_bps.shape[2])

    def contention_level(self, other_users: np.ndarray | int) -> np.ndarray | int:
        """Bandwidth pool level for a server with ``other_users`` active users besides us."""
        return np.minimum(other_users, self.n_contention_levels - 1)

    def copy_latency(self, step: int, server: int, other_users: int) -> CopyLatency:
        """Eq. 1 for step ``step``'s copy on ``server`` when ``other_users`` are already active
        there (the copy is admitted, so it runs as process number ``other_users + 1``)."""
        level = min(other_users, self.n_contention_levels - 1)
        return copy_latency(
            input_bytes=self.input_bytes[step],
            output_bytes=self.output_bytes[step],
            server_uplink_bps=self.server_uplink_by_level_bps[step, server, level],
            server_downlink_bps=self.server_downlink_by_level_bps[step, server, level],
            user_uplink_bps=self.user_uplink_bps[step],
            user_downlink_bps=self.user_downlink_bps[step],
            propagation_s=self.rtt_s[step, server],
            compute_s=self.compute_by_processes_s[step, server, other_users],
        )

    def copy_latency_table_s(self) -> np.ndarray:
        """Eq. 1 latency of every (step, server) copy when the project's own earlier copies
        have finished (the default one-request-per-minute case); ``inf`` where the server
        refuses (background load at the limit)."""
        steps = np.arange(self.n_steps)[:, None]
        servers = np.arange(self.n_servers)[None, :]
        busy = self.background_users
        admitted = busy < self.max_load
        others = np.minimum(busy, self.max_load - 1)
        level = self.contention_level(others)
        latency = copy_latency_s(
            self.input_bytes[:, None],
            self.output_bytes[:, None],
            self.server_uplink_by_level_bps[steps, servers, level],
            self.server_downlink_by_level_bps[steps, servers, level],
            self.user_uplink_bps[:, None],
            self.user_downlink_bps[:, None],
            self.rtt_s,
            self.compute_by_processes_s[steps, servers, others],
        )
        return np.where(admitted, latency, np.inf)

    def observation(self, step: int, active_users: np.ndarray, *, label: int | None = None,
                    server_max_load: np.ndarray | None = None,
                    median_propagation_s: np.ndarray | None = None) -> Observation:
        """ω^t at step ``step`` given each server's current number of active users ℓ_i.

        Args:
            step: the world step whose draws the request uses.
            active_users: ℓ_i per server.
            label: the ``step`` recorded in the observation (default ``step``; the contention
                world draws its requests in blocks and labels them by their index in the run).
            server_max_load: each server's load limit (default ``max_load`` everywhere).
            median_propagation_s: ρ^μ_i of this request's user (default the topology user's).
        """
        active = np.asarray(active_users, dtype=np.int64)
        # Called once per request: flat takes on small arrays keep it to a few microseconds.
        n_levels = self.n_contention_levels
        flat = self._server_offsets + np.minimum(active, n_levels - 1)
        processes = np.minimum(active, published.MAX_PROCESSES)
        return Observation(
            server_uplink_bps=self.server_uplink_by_level_bps[step].ravel().take(flat),
            server_downlink_bps=self.server_downlink_by_level_bps[step].ravel().take(flat),
            server_memory_util=_MEMORY_UTIL.take(processes),
            server_cpu_util=_CPU_UTIL.take(processes),
            server_active_users=active,
            server_median_propagation_s=(self.median_propagation_s if median_propagation_s is None
                                         else median_propagation_s),
            input_bytes=float(self.input_bytes[step]),
            est_output_bytes=float(self.est_output_bytes[step]),
            gamma=self.gamma[step],
            user_location=self._user_location,
            user_uplink_bps=float(self.user_uplink_bps[step]),
            user_downlink_bps=float(self.user_downlink_bps[step]),
            server_max_load=self._max_load_per_server if server_max_load is None else server_max_load,
            step=int(step if label is None else label),
        )

    @cached_property
    def hop_tables(self) -> HopTables:
        """The per-copy lookups of :class:`~yafs_safetail.sim.hooks.EdgeModel` as plain lists
        (built once per world and shared by every method's model)."""
        steps = self.n_steps
        return HopTables(
            background_users=self.background_users.tolist(),
            rtt_s=self.rtt_s.tolist(),
            input_transfer_s=self.input_transfer_by_level_s.reshape(steps, -1).tolist(),
            output_transfer_s=self.output_transfer_by_level_s.reshape(steps, -1).tolist(),
            compute_s=self.compute_by_processes_s.reshape(steps, -1).tolist(),
            target_s=self.target_s.tolist(),
        )

    @cached_property
    def _server_offsets(self) -> np.ndarray:
        return np.arange(self.n_servers) * self.n_contention_levels

    @cached_property
    def _max_load_per_server(self) -> np.ndarray:
        limits = np.full(self.n_servers, self.max_load, dtype=np.int64)
        limits.setflags(write=False)
        return limits

    @cached_property
    def _user_location(self) -> np.ndarray:
        return self.scenario.user_location


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

    The link BW and PR of the topology act on the trace pools (:func:`link_scales`). With the
    landed fallback rule the on-device fallback latency is the use case's, raised to the
    worst-case edge latency of this topology if that is higher, so a fallback is never faster
    than an edge reply and Oracle stays a per-request lower bound. With a calibrated rule it is
    a multiple of the use case's median one-process compute time (assumption iv: the on-device
    version's run time); then a method whose chosen servers all refuse may beat Oracle on that
    request, when Oracle's admitted copies are slower than the device.

    Raises:
        WorldError: inconsistent sizes or parameters.
    """
    if n_steps < 1 or episode_steps < 1:
        raise WorldError(f"n_steps and episode_steps must be >= 1, got {n_steps}, {episode_steps}")
    if not 1 <= max_load <= inputs.max_processes:
        raise WorldError(
            f"max_load: {max_load} needs compute times for k = 1..{max_load} processes but "
            f"{inputs.source} covers k = 1..{inputs.max_processes}"
        )
    nu = use_case.nu if settings.nu is None else settings.nu
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
    scales = link_scales(scenario)
    if settings.fallback_compute_multiple is None:
        worst_s = worst_case_copy_latency_s(
            inputs, use_case, max_load,
            bandwidth_scale=min(float(scales.server_bandwidth.min()), scales.user_bandwidth),
            extra_propagation_s=float(scales.server_extra_propagation_s.max()),
        )
        # Rounded up to 0.1 s so the recorded value reads cleanly in results.
        fallback_latency_s = max(float(use_case.fallback_latency_s), math.ceil(worst_s * 10) / 10)
    else:
        fallback_latency_s = settings.fallback_compute_multiple * float(inputs.median_compute_by_k_s[0])

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
    target_compute_s = target_compute_by_request_s(inputs, requests.gamma, nu, settings.target_compute)
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
            median_propagation_s[None, :], target_compute_s), dtype=float)
        if settings.target_latency_s is None else np.full(n_steps, settings.target_latency_s),
        fallback_latency_s=fallback_latency_s,
        nu=nu,
        settings=settings,
    )
