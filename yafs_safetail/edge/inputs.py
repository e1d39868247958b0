"""What a world is drawn from: the loaded traces and compute model of one use case, checked.

:func:`load_inputs` reads a traces folder (``traces/``) and the use case's shipped compute model;
:class:`TraceInputs` holds them in the form the sampling needs (sorted pools, the requests'
sizes and Γ, the model's batch prediction, σ_k, the per-k medians), and
:func:`worst_case_copy_latency_s` bounds what any admitted copy can take under them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from yafs_safetail.edge import published
from yafs_safetail.edge.compute import ComputeModel
from yafs_safetail.edge.latency import copy_latency_s
from yafs_safetail.edge.scenario import EdgeScenario, load_scenario
from yafs_safetail.edge.traces import DEFAULT_TRACE_DIR, TraceSet, load_traces
from yafs_safetail.edge.usecases import UseCase

#: Compute noise z ~ N(0, 1) is clipped to ±this many σ_k, so the worst-case edge latency
#: (and hence the on-device fallback bound) is finite; clipping touches 6e-5 of the draws.
NOISE_CLIP_SIGMAS = 4.0


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


def load_scenario_for(inputs: TraceInputs, topology: Path, placement: Path) -> EdgeScenario:
    """The topology and placement, checked against these traces (every link's distance
    condition has an RTT pool, every server's load device exists)."""
    return load_scenario(topology, placement, known_conditions=inputs.rtt_pools_s.keys(),
                         n_load_devices=inputs.n_load_devices)
