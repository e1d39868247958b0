"""A phase's world once drawn: :class:`EdgeWorld`, its arrays, and the tables read from them.

Every method evaluated on a phase runs its own simulation over the same :class:`EdgeWorld`, so
a copy of step *t*'s request sent to server *i* has the same latency whichever subset it was
part of (common random numbers), and, in the landed world, Oracle (all servers) is a
per-request lower bound. ``edge.world.build_world`` draws it; this module only holds and reads
it (Eq. 1 per copy, ω^t per step, the per-copy lookups of the simulation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from yafs_safetail.edge import published
from yafs_safetail.edge.calibration import WorldSettings
from yafs_safetail.edge.energy import EnergyModel
from yafs_safetail.edge.failures import DownIntervals, FailureSettings
from yafs_safetail.edge.latency import CopyLatency, copy_latency, copy_latency_s
from yafs_safetail.edge.observation import Observation
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.usecases import UseCase

if TYPE_CHECKING:
    from yafs_safetail.edge.movement import Movement

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
        input_bytes: Size(I) per [step] (a copy's upload energy).
        output_bytes: Size(O) per [step] (a received reply's download energy).
    """

    background_users: list[list[int]]
    rtt_s: list[list[float]]
    input_transfer_s: list[list[float]]
    output_transfer_s: list[list[float]]
    compute_s: list[list[float]]
    target_s: list[float]
    input_bytes: list[float]
    output_bytes: list[float]


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
        failures: the failure settings it was drawn with (default: no failures).
        down_intervals: each server's outages over the phase (from the phase's ``"failures"``
            stream and the scripted file); None: no server ever fails.
        timeout_s: how long the user waits for a first reply (``edge.failures.effective_timeout_s``;
            ``inf`` with failures off, so every latency is the paper's).
        energy: the servers' and the user device's power models.
        movement: where the user sends each request from and what that makes of each link
            (``edge.movement``); None: the user stays at the topology's position, and
            ``median_propagation_s`` holds at every step.
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
    failures: FailureSettings = field(default_factory=FailureSettings)
    down_intervals: DownIntervals | None = None
    timeout_s: float = math.inf
    energy: EnergyModel = field(default_factory=EnergyModel)
    movement: Movement | None = None

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
                    median_propagation_s: np.ndarray | None = None,
                    server_condition: np.ndarray | None = None,
                    user_location: np.ndarray | None = None) -> Observation:
        """ω^t at step ``step`` given each server's current number of active users ℓ_i.

        Args:
            step: the world step whose draws the request uses.
            active_users: ℓ_i per server.
            label: the ``step`` recorded in the observation (default ``step``; the contention
                world draws its requests in blocks and labels them by their index in the run).
            server_max_load: each server's load limit (default ``max_load`` everywhere).
            median_propagation_s: ρ^μ_i of this request's user (default the topology user's).
            server_condition: the links' conditions of this request's user (default the
                topology user's), with ``median_propagation_s``.
            user_location: where this request's user is (default the topology user's, or the
                phase's movement's).
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
            server_median_propagation_s=(median_propagation_s if median_propagation_s is not None
                                         else self.median_propagation_s if self.movement is None
                                         else self.movement.median_propagation_s[step]),
            input_bytes=float(self.input_bytes[step]),
            est_output_bytes=float(self.est_output_bytes[step]),
            gamma=self.gamma[step],
            user_location=(user_location if user_location is not None
                           else self._user_location if self.movement is None
                           else self.movement.user_position_m[step]),
            user_uplink_bps=float(self.user_uplink_bps[step]),
            user_downlink_bps=float(self.user_downlink_bps[step]),
            server_max_load=self._max_load_per_server if server_max_load is None else server_max_load,
            step=int(step if label is None else label),
            server_condition=(server_condition if server_condition is not None
                              else self._conditions if self.movement is None
                              else self.movement.conditions[step]),
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
            input_bytes=self.input_bytes.tolist(),
            output_bytes=self.output_bytes.tolist(),
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
    def _conditions(self) -> np.ndarray:
        conditions = np.asarray(self.scenario.server_conditions, dtype=np.int64)
        conditions.setflags(write=False)
        return conditions

    @cached_property
    def _user_location(self) -> np.ndarray:
        return self.scenario.user_location
