"""The draws of a world, one function per quantity (``world.build_world`` assembles them).

Common random numbers: a phase (e.g. ``"train"`` or ``"test"``) of a run is fully determined by
``(seed, phase)`` (:func:`phase_seed_sequence`); each quantity is drawn from its own child
stream, and each server's from a stream of its own, so removing a server leaves the others'
draws unchanged. Draws that depend on the live simulation state (a server's contention level,
its number of processes) are stored as uniform quantiles or standard-normal draws for every
possible state, so the simulation only looks values up: a quantile ``u`` maps into a sorted
pool as ``pool[floor(u * len(pool))]``, so the same draw gives a lower bandwidth at a higher
contention level (monotone coupling).

Units: seconds, bytes, bits per second.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from yafs_safetail.edge import published
from yafs_safetail.edge.inputs import NOISE_CLIP_SIGMAS, TraceInputs, WorldError
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.usecases import UseCase

#: A compute time never drops below this (a Gaussian tail must not make it zero or negative).
MIN_COMPUTE_S = 1e-3
#: The traces' uncontended bandwidth: a topology link with this BW uses the pools as measured.
REFERENCE_LINK_BPS = published.UNCONTENDED_BANDWIDTH_BPS


def phase_seed_sequence(seed: int, phase: str) -> np.random.SeedSequence:
    """The root of every draw of ``phase`` in a run seeded with ``seed``.

    The phase name enters through a CRC-32 so that ``"train"`` and ``"test"`` get independent
    streams that are stable across Python versions (unlike ``hash``).
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise WorldError(f"seed: expected a non-negative integer, got {seed!r}")
    return np.random.SeedSequence([int(seed), zlib.crc32(phase.encode("utf-8"))])


def quantile_lookup(sorted_pool: np.ndarray, quantiles: np.ndarray) -> np.ndarray:
    """``sorted_pool[floor(u * len)]`` for each quantile ``u`` in [0, 1)."""
    index = np.minimum((quantiles * sorted_pool.shape[0]).astype(np.int64), sorted_pool.shape[0] - 1)
    return sorted_pool[index]


@dataclass(frozen=True)
class LinkScales:
    """What the topology's link BW and PR do to the trace pools.

    The distance condition of a server's link picks the measured WiFi RTT pool; BW and PR
    describe the links themselves: BW scales the measured bandwidths relative to the traces'
    uncontended 20 Mbit/s, and PR (s) is wired propagation added to every transfer's ρ_i on top
    of the WiFi RTT (YAFS's per-hop meaning of PR).

    Attributes:
        server_bandwidth: per server index, its access-point link's bandwidth / 20 Mbit/s;
            multiplies the server's λ^u_i and λ^d_i pools.
        user_bandwidth: the user's access-point link bandwidth / 20 Mbit/s; multiplies Λ^u, Λ^d.
        server_extra_propagation_s: per server index, the PR of its access-point link plus the
            PR of the user's access-point link; added to ρ_i and ρ^μ_i.
    """

    server_bandwidth: np.ndarray
    user_bandwidth: float
    server_extra_propagation_s: np.ndarray


def link_scales(scenario: EdgeScenario) -> LinkScales:
    """The topology's link bandwidths and PR as changes to the trace pools (none for the shipped
    files, whose links have 20 Mbit/s and PR 0)."""
    return LinkScales(
        server_bandwidth=np.asarray(scenario.server_link_bandwidth_bps, dtype=float) / REFERENCE_LINK_BPS,
        user_bandwidth=float(scenario.user_link_bandwidth_bps) / REFERENCE_LINK_BPS,
        server_extra_propagation_s=np.asarray(scenario.server_link_pr_s, dtype=float)
        + float(scenario.user_link_pr_s),
    )


@dataclass(frozen=True)
class ServerDraws:
    """Per (step, server): bandwidth quantiles (uplink, downlink), RTT quantile, compute noise."""

    bandwidth_quantiles: np.ndarray
    rtt_quantiles: np.ndarray
    noise: np.ndarray


def draw_servers(servers_seq: np.random.SeedSequence, n_servers: int, n_steps: int) -> ServerDraws:
    """Each server's draws from its own stream; compute noise z ~ N(0, 1) clipped to ±4."""
    bandwidth = np.empty((n_steps, n_servers, 2))
    rtt = np.empty((n_steps, n_servers))
    noise = np.empty((n_steps, n_servers))
    for server, stream in enumerate(servers_seq.spawn(n_servers)):
        rng = np.random.default_rng(stream)
        bandwidth[:, server, :] = rng.random((n_steps, 2))
        rtt[:, server] = rng.random(n_steps)
        noise[:, server] = rng.standard_normal(n_steps)
    return ServerDraws(bandwidth, rtt, np.clip(noise, -NOISE_CLIP_SIGMAS, NOISE_CLIP_SIGMAS))


@dataclass(frozen=True)
class RequestDraws:
    """Per step: the compute-trace row a request copies, its sizes and its Γ."""

    rows: np.ndarray
    input_bytes: np.ndarray
    output_bytes: np.ndarray
    est_output_bytes: np.ndarray
    gamma: np.ndarray


def draw_requests(rng: np.random.Generator, inputs: TraceInputs, use_case: UseCase,
                  n_steps: int) -> RequestDraws:
    """Each step's request: a uniformly drawn compute-trace row, then its actual output size."""
    rows = rng.integers(0, inputs.request_input_bytes.shape[0], size=n_steps)
    input_bytes = inputs.request_input_bytes[rows].astype(float)
    output_bytes = np.asarray(use_case.draw_output_bytes(input_bytes, rng), dtype=float)
    return RequestDraws(
        rows=rows,
        input_bytes=input_bytes,
        output_bytes=output_bytes,
        est_output_bytes=np.asarray(use_case.estimate_output_bytes(input_bytes), dtype=float),
        gamma=inputs.request_gamma[rows].astype(float),
    )


def draw_user_bandwidth(rng: np.random.Generator, inputs: TraceInputs, scale: float,
                        n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Λ^u, Λ^d per step from the uncontended pools (contention level 0), scaled by the link."""
    quantiles = rng.random((n_steps, 2))
    uplink = scale * quantile_lookup(inputs.server_uplink_pools_bps[0], quantiles[:, 0])
    downlink = scale * quantile_lookup(inputs.server_downlink_pools_bps[0], quantiles[:, 1])
    return uplink, downlink


def draw_background_load(episode_seq: np.random.SeedSequence, load_levels: np.ndarray,
                         devices: np.ndarray, n_steps: int, episode_steps: int,
                         per_server: bool) -> tuple[np.ndarray, np.ndarray]:
    """Background users per (step, server) and the load-trace minute of each step.

    Every episode starts the trace at a random minute and advances one minute per step: one
    minute shared by all servers, or (``per_server``) one per server from the server's own
    stream, so removing a server leaves the others' loads unchanged; ``load_row`` then records
    the first server's minute.
    """
    minutes = load_levels.shape[0]
    n_episodes = -(-n_steps // episode_steps)
    starts = np.random.default_rng(episode_seq).integers(0, minutes, size=n_episodes)
    step_index = np.arange(n_steps)
    load_row = (starts[step_index // episode_steps] + step_index % episode_steps) % minutes
    if not per_server:
        return load_row, load_levels[load_row][:, devices].astype(np.int64)
    server_starts = np.stack([
        np.random.default_rng(stream).integers(0, minutes, size=n_episodes)
        for stream in episode_seq.spawn(devices.shape[0])
    ], axis=1)
    rows = (server_starts[step_index // episode_steps] + (step_index % episode_steps)[:, None]) % minutes
    return rows[:, 0], load_levels[rows, devices[None, :]].astype(np.int64)


def bandwidth_by_level(inputs: TraceInputs, quantiles: np.ndarray, server_scale: np.ndarray,
                       share_exponent: float) -> tuple[np.ndarray, np.ndarray]:
    """λ^u_i, λ^d_i per (step, server, contention level): each level's pool at the same
    quantile, scaled by the server's link and shared as 1 / (1 + level)^share_exponent beyond
    what the WiFi measurement at that level contains (exponent 0: the pools as measured)."""
    n_steps, n_servers = quantiles.shape[:2]
    levels = inputs.n_contention_levels
    uplink = np.empty((n_steps, n_servers, levels))
    downlink = np.empty((n_steps, n_servers, levels))
    for level in range(levels):
        uplink[:, :, level] = quantile_lookup(inputs.server_uplink_pools_bps[level], quantiles[..., 0])
        downlink[:, :, level] = quantile_lookup(inputs.server_downlink_pools_bps[level], quantiles[..., 1])
    share = (1.0 + np.arange(levels)) ** -share_exponent
    uplink *= server_scale[None, :, None] * share[None, None, :]
    downlink *= server_scale[None, :, None] * share[None, None, :]
    return uplink, downlink


def propagation(inputs: TraceInputs, conditions: tuple[int, ...], quantiles: np.ndarray,
                extra_s: np.ndarray, rtt_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """ρ_i per (step, server) and ρ^μ_i per server: a fraction of a ping round trip from the
    server's condition pool, plus the wired propagation of its links."""
    n_steps, n_servers = quantiles.shape
    rtt_s = np.empty((n_steps, n_servers))
    median_s = np.empty(n_servers)
    for server, condition in enumerate(conditions):
        pool = inputs.rtt_pools_s[condition] * rtt_fraction
        rtt_s[:, server] = quantile_lookup(pool, quantiles[:, server]) + extra_s[server]
        median_s[server] = float(np.median(pool)) + extra_s[server]
    return rtt_s, median_s


def compute_by_processes(inputs: TraceInputs, gamma: np.ndarray, noise: np.ndarray,
                         max_load: int) -> np.ndarray:
    """Compute time per (step, server, k - 1) for k = 1..max_load: the model's prediction for
    the request at k processes (evaluated once, batched) plus σ_k·z, floored at 1 ms."""
    n_steps = gamma.shape[0]
    ks = np.arange(1, max_load + 1)
    predictions = inputs.predict_compute_s(
        np.repeat(gamma, ks.size, axis=0), np.tile(ks, n_steps)
    ).reshape(n_steps, ks.size)
    sigma = inputs.compute_sigma_s[: ks.size]
    compute = predictions[:, None, :] + noise[:, :, None] * sigma[None, None, :]
    return np.maximum(compute, MIN_COMPUTE_S)
