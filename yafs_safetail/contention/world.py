"""The contention world: the edge world's traces and topology, with many users at once.

What changes from the paper's single-user world (``edge.world``), and what does not:

* **Users.** U users send requests as Poisson streams (a rate per user, or an offered load that
  sets it) or at the times of an arrivals CSV (``time_s,user``). Every request draws its own
  size, Γ, signal conditions (Λ^u, Λ^d), per-server RTT and compute noise exactly as a step of
  the single-user world does (the same parts, ``edge.world_parts``, drawn in blocks). Each
  user has its own distance condition to each server (``user_conditions``): the topology's
  (every user where the topology's user is), generated around it, or read from a JSON file;
  its RTTs, ρ^μ_i and τ follow from them. With ``mobility`` on, the users move instead
  (``contention.moving_users``): each request's conditions follow its user's distances then.
* **Servers.** A copy holds one of its server's slots while it computes (``capacity``, default
  Table I's load limit 4; the topology may set it per server); a full server refuses (the
  paper) or queues the copy FIFO (option). The running copies and the background tenants share
  the server's CPU equally (processor sharing); each progresses at T(1)/T(n) of its one-process
  speed when n run, T(k) being the traces' median compute time at k processes (beyond the traced
  k, in proportion to n), times the server's IPT over ``REFERENCE_SERVER_IPT``.
* **Links.** Each server has a down link (the copies' inputs) and an up link (their replies).
  The transfers on a link and the server's background tenants share it (processor sharing over
  the transfer's duration, ``links="shared"``): a transfer progresses at the measured bandwidth
  of contention level L = the tenants plus the other transfers on that link, re-read whenever
  either changes; the traces measured what an equal share of the WiFi gives at each L, each
  request's own Λ^u, Λ^d capping it as in Eq. 1. Copies computing or waiting do not use a
  link. ``links="at-start"`` keeps the single-user world's reading instead: the level is the
  number of other users active at the server (ours and background) when the transfer starts.
* **Background tenants.** The load trace's users, as in the single-user world, change every
  ``background_period_s`` (one trace row, 60 s); they hold slots and CPU share but send nothing.
* **Failures** (beyond the paper, off by default). Each server's outages over the run
  (``edge.failures.phase_down_intervals``, drawn from the phase's own ``"failures"`` stream, so no
  other draw moves); a copy on a server that fails is lost and a request without a reply by its
  time-out takes the on-device fallback (``edge.failures.effective_timeout_s`` of
  :attr:`ContentionWorld.worst_case_copy_latency_s`).
* **Energy.** Every copy's server energy (the per-process power × its time computing) and the
  device's radio energy of its upload and of each reply it receives (``edge.energy``).

Units: seconds, bytes, bits per second; rates in requests per second.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cached_property
from pathlib import Path

import numpy as np

from yafs_safetail.contention.compute_speed import ObservedLoadTarget, compute_speed_table
from yafs_safetail.contention.config import (
    DEFAULT_BLOCK_REQUESTS,
    LINK_MODELS,
    ContentionConfig,
    ContentionError,
    check_contention_config,
    read_arrivals,
    user_conditions,
)
from yafs_safetail.contention.engine import EngineSettings, RequestBlock, ServerSpec
from yafs_safetail.contention.moving_users import MovingUsers
from yafs_safetail.edge.calibration import world_settings
from yafs_safetail.edge.failures import DownIntervals, effective_timeout_s, phase_down_intervals
from yafs_safetail.edge.inputs import TraceInputs, worst_case_copy_latency_s
from yafs_safetail.edge.latency import target_latency_s
from yafs_safetail.edge.movement import Movement
from yafs_safetail.edge.observation import Observation
from yafs_safetail.edge.sampling import draw_servers, link_scales, phase_seed_sequence, propagation
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.topology_io import REFERENCE_SERVER_IPT
from yafs_safetail.edge.world import DEFAULT_MAX_LOAD, EdgeWorld, phase_streams
from yafs_safetail.edge.world_parts import OnWorldParts, WorldParts, read_world_parts
from yafs_safetail.settings.world import WorldOverrideError, apply_world_overrides
from yafs_safetail.worlds.recipe import mobility_plan

__all__ = [
    "BACKGROUND_PERIOD_S", "ContentionWorld",
    # From contention.compute_speed (importable from here, as before it moved).
    "compute_speed_table",
    # From contention.config (importable from here, as before the split).
    "DEFAULT_BLOCK_REQUESTS", "LINK_MODELS", "ContentionConfig", "ContentionError",
    "check_contention_config", "read_arrivals", "user_conditions",
]

#: How often the background tenants change: one load-trace row (a minute).
BACKGROUND_PERIOD_S = 60.0
#: Outages are drawn up to the last emission plus this many time-outs: the requests' copies
#: have settled by then (a copy still running later meets no new outage).
FAILURE_HORIZON_TIMEOUTS = 10.0


class ContentionWorld(OnWorldParts):
    """The inputs of one contention run, drawn from ``(seed, phase)``; shared by every method
    run on it (common random numbers: the same arrivals and per-request draws).

    Its parts (``edge.world_parts``: the use case, traces, scenario and world settings) are read
    as the experiment reads its own, and every request block and the background tenants are
    drawn through :meth:`~yafs_safetail.edge.world_parts.WorldParts.draw`; the configuration's
    ``target_latency_s``, ``load_peak_users`` and ``target_compute`` override the named world's
    settings as the experiment's options do. ``inputs`` and
    ``scenario``, read by an earlier world of the same files, are used instead of reading them
    again (they depend on neither the seed nor the phase).
    """

    def __init__(self, config: ContentionConfig, inputs: TraceInputs | None = None,
                 scenario: EdgeScenario | None = None) -> None:
        check_contention_config(config, style="field")  # a Python API: named as its fields
        self.config = config
        try:  # the named world with the run's overrides, as the experiment applies its own
            settings, _ = apply_world_overrides(world_settings(config.world), config)
        except WorldOverrideError as error:
            raise ContentionError(str(error)) from None
        self.parts: WorldParts = read_world_parts(
            config.use_case, settings, config.topology, config.placement,
            config.traces_dir, inputs=inputs, scenario=scenario)
        self.max_load = DEFAULT_MAX_LOAD
        self.capacity = self.scenario.server_capacity(self.max_load)
        self.speed_factor = tuple(ipt / REFERENCE_SERVER_IPT for ipt in self.scenario.server_ipt)
        self.server_max_load = np.asarray(self.capacity, dtype=np.int64)
        self.server_max_load.setflags(write=False)
        self.emit_s, self.user = self._arrivals()
        self.conditions = user_conditions(config, self.scenario, tuple(sorted(self.inputs.rtt_pools_s)))
        self._per_user = bool(np.any(self.conditions != np.asarray(self.scenario.server_conditions)))
        plan = mobility_plan(config, self.scenario, "field", ContentionError)
        #: The users' routes (None: every user stays where its conditions put it).
        self.moving_users: MovingUsers | None = None if plan is None else MovingUsers(
            plan, self.scenario, self.inputs, self.emit_s, self.user, config.users, config.seed, config.phase)
        self._current: tuple[int, EdgeWorld] | None = None
        self._block_rtt_s: np.ndarray | None = None
        self._block_movement: Movement | None = None  # the current block's, when the users move
        # τ per request, filled a block at a time as blocks are built: a request that completes
        # after the next block has started reads its τ here instead of rebuilding its block.
        self._target_s = np.full(len(self.emit_s), np.nan)

    @property
    def n_servers(self) -> int:
        return self.scenario.n_servers

    @property
    def n_requests(self) -> int:
        return int(self.emit_s.shape[0])

    @cached_property
    def mean_work_s(self) -> float:
        """Mean one-process compute time of a request on a reference server (the traces' model
        over every trace row, without noise)."""
        rows = self.inputs.request_gamma.shape[0]
        return float(np.mean(self.inputs.predict_compute_s(self.inputs.request_gamma, np.ones(rows))))

    @property
    def mean_service_s(self) -> float:
        """The mean single-copy service time: how long a copy holds its slot on a full
        reference server (T(c)/T(1) × the mean one-process time, c = Table I's load limit), so
        load 1 is the rate at which single dispatch would keep every slot busy."""
        traced = self.inputs.median_compute_by_k_s
        return self.mean_work_s * float(traced[self.max_load - 1] / traced[0])

    @property
    def total_slots(self) -> int:
        return int(sum(self.capacity))

    def rate_for_load(self, load: float) -> float:
        """Total arrival rate (1/s) for an offered utilisation ``load``."""
        return load * self.total_slots / self.mean_service_s

    def offered_load(self) -> float:
        """The offered utilisation of this run's arrivals."""
        duration_s = float(self.emit_s[-1] - self.emit_s[0]) if self.n_requests > 1 else math.inf
        rate = (self.n_requests - 1) / duration_s if duration_s > 0 else math.inf
        return rate * self.mean_service_s / self.total_slots

    def _arrivals(self) -> tuple[np.ndarray, np.ndarray]:
        config = self.config
        if config.arrivals_csv is not None:
            return read_arrivals(Path(config.arrivals_csv), config.users)
        total_rate = (config.users * float(config.rate_per_user_hz) if config.rate_per_user_hz is not None
                      else self.rate_for_load(float(config.load or 0.0)))
        rng = np.random.default_rng(phase_seed_sequence(config.seed, f"{config.phase}:arrivals"))
        # The superposition of U Poisson streams of equal rate is one Poisson stream whose
        # arrivals belong to a user drawn uniformly.
        emit_s = np.cumsum(rng.exponential(1.0 / total_rate, config.n_requests))
        return emit_s, rng.integers(config.users, size=config.n_requests)

    def engine_settings(self, queue: bool | None = None, cancel: bool | None = None) -> EngineSettings:
        config = self.config
        background = self._background_rows() if config.background else ()
        most_background = max((max(row) for row in background), default=0)
        return EngineSettings(
            servers=tuple(
                ServerSpec(slots=slots, speed=compute_speed_table(
                    self.inputs.median_compute_by_k_s, factor, slots + most_background + 1))
                for slots, factor in zip(self.capacity, self.speed_factor, strict=True)),
            contention_levels=self.inputs.n_contention_levels,
            queue=config.queue if queue is None else queue,
            cancel=config.cancel if cancel is None else cancel,
            shared_links=config.links == "shared",
            fallback_latency_s=self.fallback_latency_s,
            background_period_s=BACKGROUND_PERIOD_S,
            background=background,
            outages=tuple(tuple(zip(starts, ends, strict=True)) for starts, ends in
                          zip(self.down_intervals.starts_s, self.down_intervals.ends_s, strict=True)),
            timeout_s=self.timeout_s,
            per_process_w=config.energy.server.per_process_w,
            radio_up_j_per_byte=8.0 * config.energy.radio.alpha_up_w_per_bps,
            radio_down_j_per_byte=8.0 * config.energy.radio.alpha_down_w_per_bps,
            radio_active_w=config.energy.radio.beta_w,
        )

    @cached_property
    def worst_case_copy_latency_s(self) -> float:
        """An upper bound on a live copy's latency when nothing else shares its server or links:
        the edge world's bound (``edge.inputs.worst_case_copy_latency_s``: the slowest bandwidth,
        longest RTT and slowest compute at up to the servers' largest capacity of processes, at
        most the traced ones),
        with the topology's link scales, stretched whole by the slowest server's IPT when it is
        below the reference (its compute takes that much longer)."""
        scales = link_scales(self.scenario)
        bound_s = worst_case_copy_latency_s(
            self.inputs, self.use_case, min(max(self.capacity), self.inputs.max_processes),
            bandwidth_scale=min(float(scales.server_bandwidth.min()), scales.user_bandwidth),
            extra_propagation_s=float(scales.server_extra_propagation_s.max()))
        return bound_s / min(1.0, min(self.speed_factor))

    @cached_property
    def timeout_s(self) -> float:
        """How long a user waits for a reply (``edge.failures.effective_timeout_s``): the
        configured time-out, else with failures on the worst-case live copy's latency, else
        never (``inf``)."""
        failures = self.config.failures
        # (The bound costs a compute-model pass; only the default time-out with failures uses it.)
        needs_bound = failures.enabled and failures.timeout_s is None
        return effective_timeout_s(failures, self.worst_case_copy_latency_s if needs_bound else math.inf)

    @cached_property
    def down_intervals(self) -> DownIntervals:
        """Each server's outages over the run, from the phase's own ``"failures"`` stream (no
        draw with failures off)."""
        failures = self.config.failures
        if not failures.enabled:
            return DownIntervals.none(self.n_servers)
        last_emit_s = float(self.emit_s[-1]) if self.n_requests else 0.0
        horizon_s = last_emit_s + FAILURE_HORIZON_TIMEOUTS * self.timeout_s
        rng = np.random.default_rng(phase_seed_sequence(self.config.seed, f"{self.config.phase}:failures"))
        return phase_down_intervals(failures, self.n_servers, horizon_s, rng)

    def _background_rows(self) -> tuple[tuple[int, ...], ...]:
        periods = int(self.emit_s[-1] // BACKGROUND_PERIOD_S) + 2 if self.n_requests else 1
        world = self.parts.draw(periods, self.config.seed, f"{self.config.phase}:background")
        return tuple(tuple(row) for row in world.background_users.tolist())

    @cached_property
    def fallback_latency_s(self) -> float:
        return self.block_world(0).fallback_latency_s

    def block_world(self, index: int) -> EdgeWorld:
        """The edge world whose steps are requests ``index * block .. (index + 1) * block - 1``
        (built once; the latest is kept)."""
        if self._current is not None and self._current[0] == index:
            return self._current[1]
        size = self.config.block_requests
        n_steps = max(1, min(size, self.n_requests - index * size))
        phase = f"{self.config.phase}:{index}"
        world = self.parts.draw(n_steps, self.config.seed, phase)
        self._current = (index, world)
        if self.moving_users is not None:
            self._block_rtt_s, self._block_movement = self.moving_users.links(
                index * size, self._rtt_quantiles(world, phase), link_scales(self.scenario).server_extra_propagation_s,
                self.settings.propagation_rtt_fraction)
            block_target_s = self._user_target_s(world, self._block_movement.median_propagation_s)
        elif self._per_user:
            users = self.user[index * size:index * size + n_steps]
            self._block_rtt_s = self._user_rtt_s(world, phase, users)
            block_target_s = self._user_target_s(world, self.user_median_propagation_s[users])
        else:
            self._block_rtt_s, block_target_s = world.rtt_s, world.target_s
        first = index * size
        count = max(0, min(n_steps, self.n_requests - first))  # (a world has at least one step)
        self._target_s[first:first + count] = block_target_s[:count]
        return world

    def _user_target_s(self, world: EdgeWorld, median_propagation_s: np.ndarray) -> np.ndarray:
        """τ (Eq. 4) of the block's requests from each one's ρ^μ_i (its user's), for the whole
        block at once; a fixed τ of the settings needs no per-user value."""
        if self.settings.target_latency_s is not None:
            return world.target_s
        return np.asarray(target_latency_s(
            world.input_bytes, world.est_output_bytes, world.user_uplink_bps, world.user_downlink_bps,
            median_propagation_s, world.target_compute_s), dtype=float)

    def _rtt_quantiles(self, world: EdgeWorld, phase: str) -> np.ndarray:
        """The RTT quantile per (request, server) the block's world drew (its own stream)."""
        servers_seq = phase_streams(self.config.seed, phase)["servers"]
        return draw_servers(servers_seq, self.n_servers, world.n_steps).rtt_quantiles

    def _user_rtt_s(self, world: EdgeWorld, phase: str, users: np.ndarray) -> np.ndarray:
        """ρ per (request, server) from each request's user's conditions, with the same RTT
        quantiles the block's world drew (so a user at the topology's conditions sees the same
        RTTs as under ``"topology"``)."""
        quantiles = self._rtt_quantiles(world, phase)
        extra_s = link_scales(self.scenario).server_extra_propagation_s
        by_condition = {c: propagation(self.inputs, (c,) * self.n_servers, quantiles, extra_s,
                                       self.settings.propagation_rtt_fraction)[0]
                        for c in np.unique(self.conditions).tolist()}
        rtt_s = np.empty_like(world.rtt_s)
        for c, table in by_condition.items():
            mask = self.conditions[users] == c
            rtt_s[mask] = table[mask]
        return rtt_s

    @cached_property
    def user_median_propagation_s(self) -> np.ndarray:
        """ρ^μ_i per (user, server) from the users' conditions."""
        extra_s = link_scales(self.scenario).server_extra_propagation_s
        fraction = self.settings.propagation_rtt_fraction
        medians = {c: float(np.median(self.inputs.rtt_pools_s[c] * fraction))
                   for c in np.unique(self.conditions).tolist()}
        return np.vectorize(medians.__getitem__, otypes=[float])(self.conditions) + extra_s[None, :]

    def block(self, index: int) -> RequestBlock:
        world = self.block_world(index)
        n = world.n_steps
        assert self._block_rtt_s is not None  # set with the block's world
        return RequestBlock(
            first=index * self.config.block_requests,
            input_transfer_s=world.input_transfer_by_level_s.reshape(n, -1).tolist(),
            output_transfer_s=world.output_transfer_by_level_s.reshape(n, -1).tolist(),
            propagation_s=self._block_rtt_s.tolist(),
            work_s=world.compute_by_processes_s[:, :, 0].tolist(),
            input_bytes=np.asarray(world.input_bytes, dtype=float).tolist(),
            output_bytes=np.asarray(world.output_bytes, dtype=float).tolist(),
        )

    def observation(self, request: int, active_users: list[int]) -> Observation:
        """ω^t of request ``request`` (its block must be the current one)."""
        size = self.config.block_requests
        world = self.block_world(request // size)
        if self._block_movement is not None:  # where the request's user is now
            movement, step = self._block_movement, request % size
            return world.observation(
                step, np.asarray(active_users, dtype=np.int64), label=request, server_max_load=self.server_max_load,
                median_propagation_s=movement.median_propagation_s[step],
                server_condition=movement.conditions[step], user_location=movement.user_position_m[step])
        return world.observation(
            request % size, np.asarray(active_users, dtype=np.int64), label=request,
            server_max_load=self.server_max_load,
            median_propagation_s=self.user_median_propagation_s[self.user[request]] if self._per_user else None,
            server_condition=self.conditions[self.user[request]] if self._per_user else None)

    def target_s(self, request: int) -> float:
        """τ (Eq. 4) of request ``request``, from its user's ρ^μ_i."""
        target_s = self._target_s[request]
        if target_s != target_s:  # NaN: its block has not been built yet
            self.block_world(request // self.config.block_requests)
            target_s = self._target_s[request]
        return float(target_s)

    def observed_load_target_s(self, request: int, active_users: Sequence[int]) -> float:
        """τ of request ``request`` with its compute term at the servers' observed load instead
        of ν (the ``observed-load`` target, beyond the paper: docs/deviations.md D12;
        :class:`~yafs_safetail.contention.compute_speed.ObservedLoadTarget`). A fixed τ of the
        settings (``target_latency_s``) stays fixed."""
        target_s = self.target_s(request)
        if self.settings.target_latency_s is not None:
            return target_s
        size = self.config.block_requests
        world = self.block_world(request // size)
        return self._observed_load_target.target_s(
            target_s, float(world.target_compute_s[request % size]), world.nu, active_users)

    @cached_property
    def _observed_load_target(self) -> ObservedLoadTarget:
        return ObservedLoadTarget(self.capacity, self.inputs.median_compute_by_k_s)
