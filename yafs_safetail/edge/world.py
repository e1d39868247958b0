"""The pre-drawn world: every random quantity of a phase, drawn up front.

Common random numbers: a phase (e.g. ``"train"`` or ``"test"``) of a run is fully determined
by ``(seed, phase)``. Everything random — the request stream, the user's bandwidths, the
episode start rows of the load trace, and per (step, server) the bandwidth draws, the RTT
draw and the compute noise — is drawn here with NumPy Generators, each quantity from its own
child stream of one ``SeedSequence``. Every method evaluated on the phase runs its own
simulation over the same :class:`EdgeWorld`, so a copy of step *t*'s request sent to server
*i* has the same latency whichever subset it was part of, and Oracle (all servers) is a
per-request lower bound.

Random draws that depend on the live simulation state (the contention level of a server's
bandwidth, the number of processes k for the compute time) are stored as *uniform quantiles*
or *standard-normal draws* for every possible state, so the simulation only looks values up.
A quantile ``u`` maps into a sorted pool as ``pool[floor(u * len(pool))]``, so the same draw
gives a lower bandwidth at a higher contention level (monotone coupling).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from yafs_safetail.edge import calibration, published
from yafs_safetail.edge.calibration import LANDED, WorldSettings
from yafs_safetail.edge.compute import ComputeModel
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
from yafs_safetail.edge.topology_io import EdgeScenario
from yafs_safetail.edge.traces import DEFAULT_TRACE_DIR, TraceSet, load_traces
from yafs_safetail.edge.usecases import UseCase

#: Compute noise z ~ N(0, 1) is clipped to ±this many σ_k, so the worst-case edge latency
#: (and hence the on-device fallback bound) is finite; clipping touches 6e-5 of the draws.
NOISE_CLIP_SIGMAS = 4.0
#: A compute time never drops below this (a Gaussian tail must not make it zero or negative).
MIN_COMPUTE_S = 1e-3
#: Paper Table I: maximum load of each edge server.
DEFAULT_MAX_LOAD = 4
#: Paper Table I: α_s, steps per episode.
DEFAULT_EPISODE_STEPS = 256


class WorldError(ValueError):
    """The inputs cannot make a consistent world (one line naming what is wrong)."""


@dataclass(frozen=True)
class TraceInputs:
    """Everything the world draws from, already loaded and checked by the trace loaders.

    Attributes:
        source: where the inputs came from (for messages).
        server_uplink_pools_bps: λ^u pool per contention level 0..L-1 (extra users on the
            WiFi), each sorted ascending.
        server_downlink_pools_bps: λ^d pools, same layout.
        rtt_pools_s: RTT pool (sorted) per distance condition.
        load_users: active users per minute and load device, shape (minutes, devices), as in
            the load trace (the world scales them into background users, see
            :func:`yafs_safetail.edge.calibration.load_levels`).
        request_gamma: Γ of every compute-trace row (without the number of processes),
            shape (rows, g), possibly g = 0.
        request_input_bytes: Size(I) of every compute-trace row, shape (rows,).
        predict_compute_s: the compute model's batch prediction ``f(gamma_rows, k_rows)``.
        compute_sigma_s: σ_k for k = 1..K, shape (K,).
        median_compute_by_k_s: median measured compute latency per k = 1..K, shape (K,).
        max_compute_by_k_s: largest measured compute latency per k, shape (K,).
    """

    source: str
    server_uplink_pools_bps: tuple[np.ndarray, ...]
    server_downlink_pools_bps: tuple[np.ndarray, ...]
    rtt_pools_s: Mapping[int, np.ndarray]
    load_users: np.ndarray
    request_gamma: np.ndarray
    request_input_bytes: np.ndarray
    predict_compute_s: Callable[[np.ndarray, np.ndarray], np.ndarray]
    compute_sigma_s: np.ndarray
    median_compute_by_k_s: np.ndarray
    max_compute_by_k_s: np.ndarray

    @property
    def n_contention_levels(self) -> int:
        return len(self.server_uplink_pools_bps)

    @property
    def max_processes(self) -> int:
        return int(self.compute_sigma_s.shape[0])

    @property
    def n_load_devices(self) -> int:
        return int(self.load_users.shape[1])


def _quantile_lookup(sorted_pool: np.ndarray, quantiles: np.ndarray) -> np.ndarray:
    index = np.minimum((quantiles * sorted_pool.shape[0]).astype(np.int64), sorted_pool.shape[0] - 1)
    return sorted_pool[index]


def phase_seed_sequence(seed: int, phase: str) -> np.random.SeedSequence:
    """The root of every draw of ``phase`` in a run seeded with ``seed``.

    The phase name enters through a CRC-32 so that ``"train"`` and ``"test"`` get independent
    streams that are stable across Python versions (unlike ``hash``).
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise WorldError(f"seed: expected a non-negative integer, got {seed!r}")
    return np.random.SeedSequence([int(seed), zlib.crc32(phase.encode("utf-8"))])


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
        median_compute_s: C(s_j) of Eq. 4, the median compute time at ν processes.
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
    median_compute_s: float
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

    def observation(self, step: int, active_users: np.ndarray) -> Observation:
        """ω^t at step ``step`` given each server's current number of active users ℓ_i."""
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
            server_median_propagation_s=self.median_propagation_s,
            input_bytes=float(self.input_bytes[step]),
            est_output_bytes=float(self.est_output_bytes[step]),
            gamma=self.gamma[step],
            user_location=self._user_location,
            user_uplink_bps=float(self.user_uplink_bps[step]),
            user_downlink_bps=float(self.user_downlink_bps[step]),
        )

    @cached_property
    def hop_tables(self) -> HopTables:
        """The per-copy lookups of :class:`~yafs_safetail.edge.model.EdgeModel` as plain lists
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
    def _user_location(self) -> np.ndarray:
        return self.scenario.user_location


def worst_case_copy_latency_s(
    inputs: TraceInputs,
    use_case: UseCase,
    max_load: int,
    bandwidth_scale: float = 1.0,
    extra_propagation_s: float = 0.0,
) -> float:
    """An upper bound on any admitted copy's Eq. 1 latency under these traces.

    Largest input (and the use case's bound on its output) over the slowest bandwidth any
    admitted copy can see, the longest RTT of any condition (twice), and the slowest compute
    time the model can produce at k ≤ max_load: its largest prediction over the trace's
    requests plus the clipped noise.

    Args:
        inputs: the traces and compute model.
        use_case: the use case.
        max_load: the server load limit.
        bandwidth_scale: the smallest bandwidth scale of the topology's links (see
            :func:`link_scales`).
        extra_propagation_s: the largest wired propagation the topology's links add.
    """
    levels = min(max_load, inputs.n_contention_levels)
    slowest_bps = bandwidth_scale * min(
        float(np.min(pool))
        for pool in (*inputs.server_uplink_pools_bps[:levels], *inputs.server_downlink_pools_bps[:levels])
    )
    longest_rtt_s = extra_propagation_s + max(float(np.max(pool)) for pool in inputs.rtt_pools_s.values())
    rows = inputs.request_gamma.shape[0]
    ks = np.arange(1, max_load + 1)
    predictions = inputs.predict_compute_s(
        np.repeat(inputs.request_gamma, ks.size, axis=0), np.tile(ks, rows)
    ).reshape(rows, ks.size)
    slowest_compute_s = float(
        np.max(predictions.max(axis=0) + NOISE_CLIP_SIGMAS * inputs.compute_sigma_s[: ks.size])
    )
    max_input = float(np.max(inputs.request_input_bytes))
    max_output = float(use_case.output_bytes_bound(max_input))
    return float(
        copy_latency_s(max_input, max_output, slowest_bps, slowest_bps, slowest_bps, slowest_bps,
                       longest_rtt_s, slowest_compute_s)
    )


#: The traces' uncontended bandwidth in the topology's BW unit (Mbit/s): a link with this BW
#: uses the bandwidth pools as measured.
REFERENCE_LINK_BW_MBPS = published.UNCONTENDED_BANDWIDTH_BPS / 1e6


@dataclass(frozen=True)
class LinkScales:
    """What the topology's link BW and PR do to the trace pools.

    The distance condition of a server's link picks the measured WiFi RTT pool; BW and PR
    describe the links themselves: BW (Mbit/s) scales the measured bandwidths relative to
    the traces' uncontended 20 Mbit/s, and PR (s) is wired propagation added to every
    transfer's ρ_i on top of the WiFi RTT (YAFS's per-hop meaning of PR).

    Attributes:
        server_bandwidth: per server index, its access-point link's BW / 20 Mbit/s; multiplies
            the server's λ^u_i and λ^d_i pools.
        user_bandwidth: the user's access-point link BW / 20 Mbit/s; multiplies Λ^u and Λ^d.
        server_extra_propagation_s: per server index, the PR of its access-point link plus
            the PR of the user's access-point link; added to ρ_i and ρ^μ_i.
    """

    server_bandwidth: np.ndarray
    user_bandwidth: float
    server_extra_propagation_s: np.ndarray


def link_scales(scenario: EdgeScenario) -> LinkScales:
    """The topology's BW/PR as changes to the trace pools (none for the shipped files, whose
    links have BW 20 and PR 0)."""
    return LinkScales(
        server_bandwidth=np.asarray(scenario.server_link_bw, dtype=float) / REFERENCE_LINK_BW_MBPS,
        user_bandwidth=float(scenario.user_link_bw) / REFERENCE_LINK_BW_MBPS,
        server_extra_propagation_s=np.asarray(scenario.server_link_pr, dtype=float)
        + float(scenario.user_link_pr),
    )


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
    load_levels = calibration.load_levels(inputs.load_users, settings.load_peak_users, max_load)

    n = scenario.n_servers
    request_seq, user_bw_seq, episode_seq, servers_seq = phase_seed_sequence(seed, phase).spawn(4)
    request_rng = np.random.default_rng(request_seq)
    user_bw_rng = np.random.default_rng(user_bw_seq)
    episode_rng = np.random.default_rng(episode_seq)
    # One stream per server index, so server i's draws do not depend on how many servers
    # the topology has (removing a server leaves the others' copies unchanged).
    server_rngs = [np.random.default_rng(s) for s in servers_seq.spawn(n)]
    bw_quantiles = np.empty((n_steps, n, 2))
    rtt_quantiles = np.empty((n_steps, n))
    noise = np.empty((n_steps, n))
    for server, rng in enumerate(server_rngs):
        bw_quantiles[:, server, :] = rng.random((n_steps, 2))
        rtt_quantiles[:, server] = rng.random(n_steps)
        noise[:, server] = rng.standard_normal(n_steps)
    noise = np.clip(noise, -NOISE_CLIP_SIGMAS, NOISE_CLIP_SIGMAS)

    rows = request_rng.integers(0, inputs.request_input_bytes.shape[0], size=n_steps)
    input_bytes = inputs.request_input_bytes[rows].astype(float)
    output_bytes = np.asarray(use_case.draw_output_bytes(input_bytes, request_rng), dtype=float)
    est_output_bytes = np.asarray(use_case.estimate_output_bytes(input_bytes), dtype=float)
    gamma = inputs.request_gamma[rows].astype(float)

    user_quantiles = user_bw_rng.random((n_steps, 2))
    user_uplink_bps = scales.user_bandwidth * _quantile_lookup(
        inputs.server_uplink_pools_bps[0], user_quantiles[:, 0])
    user_downlink_bps = scales.user_bandwidth * _quantile_lookup(
        inputs.server_downlink_pools_bps[0], user_quantiles[:, 1])

    minutes = load_levels.shape[0]
    n_episodes = -(-n_steps // episode_steps)
    starts = episode_rng.integers(0, minutes, size=n_episodes)
    step_index = np.arange(n_steps)
    load_row = (starts[step_index // episode_steps] + step_index % episode_steps) % minutes
    devices = np.asarray(scenario.server_load_devices)
    if settings.load_start == "per_server":
        # Each server's own start minute per episode, from its own stream (so removing a
        # server leaves the others' load unchanged); the shared draw above still numbers the
        # episodes' rows for load_row, which then records the first server's minute.
        server_starts = np.stack([
            np.random.default_rng(stream).integers(0, minutes, size=n_episodes)
            for stream in episode_seq.spawn(n)
        ], axis=1)
        rows = (server_starts[step_index // episode_steps]
                + (step_index % episode_steps)[:, None]) % minutes
        background = load_levels[rows, devices[None, :]].astype(np.int64)
        load_row = rows[:, 0]
    else:
        background = load_levels[load_row][:, devices].astype(np.int64)

    levels = inputs.n_contention_levels
    uplink = np.empty((n_steps, n, levels))
    downlink = np.empty((n_steps, n, levels))
    for level in range(levels):
        uplink[:, :, level] = _quantile_lookup(inputs.server_uplink_pools_bps[level], bw_quantiles[..., 0])
        downlink[:, :, level] = _quantile_lookup(inputs.server_downlink_pools_bps[level], bw_quantiles[..., 1])
    # Sharing among the server's other active users beyond what the WiFi measurement at that
    # contention level already contains (exponent 0: the pools as measured).
    share = (1.0 + np.arange(levels)) ** -settings.bandwidth_share_exponent
    uplink *= scales.server_bandwidth[None, :, None] * share[None, None, :]
    downlink *= scales.server_bandwidth[None, :, None] * share[None, None, :]

    input_transfer = transfer_s(
        input_bytes[:, None, None],
        input_bottleneck_bps(downlink, user_uplink_bps[:, None, None]),
    )
    output_transfer = transfer_s(
        output_bytes[:, None, None],
        output_bottleneck_bps(uplink, user_downlink_bps[:, None, None]),
    )

    rtt_s = np.empty((n_steps, n))
    median_propagation_s = np.empty(n)
    for server, condition in enumerate(scenario.server_conditions):
        # ρ_i per direction: a fraction of a measured ping round trip, plus wired propagation.
        pool = inputs.rtt_pools_s[condition] * settings.propagation_rtt_fraction
        extra_s = scales.server_extra_propagation_s[server]
        rtt_s[:, server] = _quantile_lookup(pool, rtt_quantiles[:, server]) + extra_s
        median_propagation_s[server] = float(np.median(pool)) + extra_s

    ks = np.arange(1, max_load + 1)
    predictions = inputs.predict_compute_s(
        np.repeat(gamma, ks.size, axis=0), np.tile(ks, n_steps)
    ).reshape(n_steps, ks.size)
    sigma = inputs.compute_sigma_s[: ks.size]
    compute = predictions[:, None, :] + noise[:, :, None] * sigma[None, None, :]
    compute = np.maximum(compute, MIN_COMPUTE_S)

    median_compute_s = float(inputs.median_compute_by_k_s[nu - 1])
    target = target_latency_s(
        input_bytes,
        est_output_bytes,
        user_uplink_bps,
        user_downlink_bps,
        median_propagation_s[None, :],
        median_compute_s,
    )
    return EdgeWorld(
        seed=int(seed),
        phase=phase,
        scenario=scenario,
        use_case=use_case,
        max_load=max_load,
        episode_steps=episode_steps,
        request_row=rows,
        input_bytes=input_bytes,
        output_bytes=output_bytes,
        est_output_bytes=est_output_bytes,
        gamma=gamma,
        user_uplink_bps=user_uplink_bps,
        user_downlink_bps=user_downlink_bps,
        load_row=load_row,
        background_users=background,
        rtt_s=rtt_s,
        median_propagation_s=median_propagation_s,
        server_uplink_by_level_bps=uplink,
        server_downlink_by_level_bps=downlink,
        input_transfer_by_level_s=input_transfer,
        output_transfer_by_level_s=output_transfer,
        compute_by_processes_s=compute,
        median_compute_s=median_compute_s,
        target_s=np.asarray(target, dtype=float),
        fallback_latency_s=fallback_latency_s,
        nu=nu,
        settings=settings,
    )


def trace_inputs(
    traces: TraceSet,
    use_case: UseCase,
    predict_compute_s: Callable[[np.ndarray, np.ndarray], np.ndarray],
    compute_sigma_s: np.ndarray | None = None,
) -> TraceInputs:
    """Assembles the world's inputs from the loaded traces of one use case.

    Args:
        traces: from :func:`yafs_safetail.edge.traces.load_traces`.
        use_case: the use case.
        predict_compute_s: the compute model's batch prediction ``f(gamma_rows, k_rows)``.
        compute_sigma_s: σ_k for k = 1..5 (default: the published σ_k of the use case).
    """
    compute = traces.compute[use_case.number]
    if compute.gamma_columns != use_case.gamma_columns:
        raise WorldError(
            f"{compute.source}: Γ columns {compute.gamma_columns} differ from use case "
            f"{use_case.number}'s {use_case.gamma_columns}"
        )
    k = compute.n_processes
    latency = compute.latency_s
    ks = np.arange(1, published.MAX_PROCESSES + 1)
    sigma = np.asarray(
        published.SIGMA_S[use_case.number] if compute_sigma_s is None else compute_sigma_s, dtype=float
    )
    return TraceInputs(
        source=str(traces.directory),
        server_uplink_pools_bps=tuple(
            np.sort(traces.bandwidth.samples_bps(level, "uplink")).astype(float)
            for level in range(traces.bandwidth.max_contention_level + 1)
        ),
        server_downlink_pools_bps=tuple(
            np.sort(traces.bandwidth.samples_bps(level, "downlink")).astype(float)
            for level in range(traces.bandwidth.max_contention_level + 1)
        ),
        rtt_pools_s={c: np.sort(traces.propagation.samples_s(c)) for c in traces.propagation.conditions},
        load_users=traces.load.users,
        request_gamma=compute.gamma_matrix(),
        request_input_bytes=compute.frame[use_case.input_bytes_column].to_numpy(dtype=float),
        predict_compute_s=predict_compute_s,
        compute_sigma_s=sigma,
        median_compute_by_k_s=np.array([np.median(latency[k == kk]) for kk in ks]),
        max_compute_by_k_s=np.array([np.max(latency[k == kk]) for kk in ks]),
    )


def load_inputs(
    use_case: UseCase,
    trace_dir: Path | str = DEFAULT_TRACE_DIR,
    compute_model: ComputeModel | None = None,
) -> TraceInputs:
    """The traces of ``trace_dir`` and the use case's shipped compute model, ready to draw from.

    Args:
        use_case: the use case.
        trace_dir: the traces folder (default: the repository's ``traces/``).
        compute_model: a compute model to use instead of ``trace_dir/models``'s.

    Raises:
        TraceError: a missing or invalid trace or model file.
    """
    model = compute_model or ComputeModel.load(use_case.number, Path(trace_dir) / "models")
    return trace_inputs(load_traces(trace_dir), use_case, model.predict_s, model.sigma_by_k_s)
