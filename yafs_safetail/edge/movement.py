"""A phase's movement: where the user is at each request, and what that does to each link.

``edge.routes`` says how the user moves (a route, or random waypoint's parameters);
``edge.signal`` says what a distance does to a link's condition. This module joins them for
one phase (:func:`draw_movement`; the contention world's users through the same
steps, :func:`positions_at_m` and :func:`links_at`):

1. each request is sent at ``step · step_interval_s`` on the phase's clock, and the user is
   where the route puts it then. A route file shorter than the phase is walked again from its
   start (a daily commute, repeated); random waypoint draws one route as long as the phase
   from the phase's own ``"mobility"`` stream;
2. each (request, server) pair gets the condition of their distance;
3. its RTT is drawn at the same quantile the world drew for that server and step, from that
   condition's pool (so a user at rest in the topology's conditions has today's RTTs
   exactly, and two methods see the same link at the same request), and its median
   propagation ρ^μ_i is the median of that pool: the observation shows it, τ uses it.

The wired part of a link (its YAFS ``PR``) is added as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from yafs_safetail.edge.inputs import TraceInputs
from yafs_safetail.edge.routes import RandomWaypoint, Route, random_waypoint
from yafs_safetail.edge.sampling import quantile_lookup
from yafs_safetail.edge.scenario import EdgeScenario
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE, SignalRule, distances_m


class MovementError(ValueError):
    """A movement the scenario cannot place (one line naming the file and what is missing)."""


@dataclass(frozen=True)
class MobilityPlan:
    """How the user moves in every phase of a run.

    Attributes:
        route: a route file's route (None with random waypoint).
        random_waypoint: random waypoint's parameters (None with a route file).
        signal: distance to condition.
    """

    route: Route | None = None
    random_waypoint: RandomWaypoint | None = None
    signal: SignalRule = DEFAULT_SIGNAL_RULE

    def __post_init__(self) -> None:
        if (self.route is None) == (self.random_waypoint is None):
            raise ValueError("a mobility plan takes a route or random waypoint's parameters, one of the two")

    @property
    def source(self) -> str:
        """The route file, or ``random-waypoint``."""
        return self.route.source if self.route is not None else "random-waypoint"


@dataclass(frozen=True)
class Movement:
    """One phase's movement, per request (step).

    Attributes:
        user_position_m: where the user sends each request from, shape (n_steps, 2).
        conditions: each link's condition at each request, shape (n_steps, n_servers).
        median_propagation_s: ρ^μ_i at each request, shape (n_steps, n_servers).
        source: the route file, or ``random-waypoint``.
    """

    user_position_m: np.ndarray
    conditions: np.ndarray
    median_propagation_s: np.ndarray
    source: str


def server_positions_m(scenario: EdgeScenario) -> np.ndarray:
    """Each server's (x, y) in server index order.

    Raises:
        MovementError: the topology places no server.
    """
    placed = scenario.topology.server_positions_m
    if not placed:
        raise MovementError(f"{scenario.topology.source}: edge servers: a user who moves needs every edge "
                            "server's position (x, y in metres, or lat, lon)")
    return np.asarray([placed[node] for node in scenario.server_nodes], dtype=float)


def default_area_m(scenario: EdgeScenario, signal: SignalRule) -> tuple[float, float, float, float]:
    """Where random waypoint draws destinations unless told: the box around the user's and the
    servers' positions, widened on every side by the distance at which the signal turns poor
    (so a walk can take the user out of every server's good range)."""
    points = np.vstack([server_positions_m(scenario), scenario.user_location[None, :]])
    margin_m = signal.distance_edges_m()[-1]
    low, high = points.min(axis=0) - margin_m, points.max(axis=0) + margin_m
    return float(low[0]), float(low[1]), float(high[0]), float(high[1])


def phase_route(plan: MobilityPlan, scenario: EdgeScenario, duration_s: float,
                rng: np.random.Generator) -> Route:
    """The route of one phase: the plan's file, or a random waypoint drawn for this phase."""
    if plan.route is not None:
        return plan.route
    assert plan.random_waypoint is not None
    start = scenario.user_location
    return random_waypoint(plan.random_waypoint, (float(start[0]), float(start[1])), duration_s, rng)


def positions_at_m(plan: MobilityPlan, route: Route, at_s: np.ndarray) -> np.ndarray:
    """Where ``route`` puts the user at each time of ``at_s``, shape (m, 2): a route file
    shorter than ``at_s`` is walked again from its start; a random waypoint covers the phase."""
    period_s = float(route.times_s[-1])
    return route.positions_m(at_s % period_s if period_s > 0 and plan.route is not None else at_s)


def links_at(plan: MobilityPlan, inputs: TraceInputs, user_m: np.ndarray, servers_m: np.ndarray,
             rtt_quantiles: np.ndarray, extra_propagation_s: np.ndarray,
             rtt_fraction: float) -> tuple[np.ndarray, Movement]:
    """Each (request, server) RTT, and the links' conditions and ρ^μ_i, from where each request
    is sent.

    Args:
        plan: how the user moves (its signal rule).
        inputs: the RTT pools per condition.
        user_m: where each request is sent from, shape (m, 2).
        servers_m: each server's position, shape (n, 2).
        rtt_quantiles: the quantile per (request, server) the world drew, shape (m, n).
        extra_propagation_s: each server's wired propagation (its links' PR).
        rtt_fraction: the share of a round trip charged per direction (the world's reading).

    Raises:
        MovementError: a condition has no RTT pool.
    """
    conditions = plan.signal.condition(distances_m(user_m, servers_m))
    missing = sorted(set(np.unique(conditions).tolist()) - set(inputs.rtt_pools_s))
    if missing:
        raise MovementError(f"{plan.source}: conditions {missing}: the propagation trace has no RTT pool for them")
    rtt_s = np.empty(conditions.shape)
    median_s = np.empty(conditions.shape)
    for condition in np.unique(conditions).tolist():
        pool = inputs.rtt_pools_s[condition] * rtt_fraction
        here = conditions == condition
        rtt_s[here] = quantile_lookup(pool, rtt_quantiles[here])
        median_s[here] = float(np.median(pool))
    extra = np.asarray(extra_propagation_s, dtype=float)[None, :]
    return rtt_s + extra, Movement(user_m, conditions, median_s + extra, plan.source)


def draw_movement(plan: MobilityPlan, scenario: EdgeScenario, inputs: TraceInputs,
                  rtt_quantiles: np.ndarray, extra_propagation_s: np.ndarray, rtt_fraction: float,
                  step_interval_s: float, rng: np.random.Generator) -> tuple[np.ndarray, Movement]:
    """Each (step, server) RTT and the phase's movement.

    Args:
        plan: how the user moves.
        scenario: the topology (the servers' positions, the user's start).
        inputs: the RTT pools per condition.
        rtt_quantiles: the world's quantile per (step, server), the same as without movement.
        extra_propagation_s: each server's wired propagation (its links' PR).
        rtt_fraction: the share of a round trip charged per direction (the world's reading).
        step_interval_s: time between two requests.
        rng: the phase's ``"mobility"`` stream (random waypoint's draws).

    Raises:
        MovementError: the topology places no server, or a condition has no RTT pool.
    """
    n_steps, _ = rtt_quantiles.shape
    send_s = np.arange(n_steps) * step_interval_s
    route = phase_route(plan, scenario, float(send_s[-1]) if n_steps else 0.0, rng)
    return links_at(plan, inputs, positions_at_m(plan, route, send_s), server_positions_m(scenario),
                    rtt_quantiles, extra_propagation_s, rtt_fraction)
