"""The contention world's users on the move: each user's route over a run, and what it does to
each request's links.

The single-user world's rules (``edge.movement``, docs/mobility.md), per user: with random
waypoint every user walks its own route from the topology's user position, drawn from its own
generator (user u's is the u-th child of the phase's ``"<phase>:mobility"`` stream, so it does
not depend on how many users there are, and no other draw of the world moves); with a route file
every user follows that route. A request's user is where its route puts it at the request's
emission time; each link's condition follows from the distance to its server, its RTT from that
condition's pool at the quantile the world drew for the request, and its ρ^μ_i (and so τ) is
that pool's median (``edge.movement.links_at``).
"""

from __future__ import annotations

import numpy as np

from yafs_safetail.edge.inputs import TraceInputs
from yafs_safetail.edge.movement import (
    MobilityPlan,
    Movement,
    links_at,
    phase_route,
    positions_at_m,
    server_positions_m,
)
from yafs_safetail.edge.routes import Route
from yafs_safetail.edge.sampling import phase_seed_sequence
from yafs_safetail.edge.scenario import EdgeScenario


class MovingUsers:
    """Every user's route over one contention run (one seed and phase).

    Attributes:
        plan: how the users move.
        routes: each user's route, in user order.
    """

    def __init__(self, plan: MobilityPlan, scenario: EdgeScenario, inputs: TraceInputs, emit_s: np.ndarray,
                 user: np.ndarray, users: int, seed: int, phase: str) -> None:
        """Draw every user's route, long enough for the run's last emission.

        Args:
            plan: how the users move.
            scenario: the topology (the servers' positions, the users' start).
            inputs: the RTT pools per condition.
            emit_s: each request's emission time.
            user: each request's user.
            users: how many users there are.
            seed: the run's seed.
            phase: the run's phase (its streams).

        Raises:
            MovementError: the topology does not place every server.
        """
        self.plan = plan
        self._inputs = inputs
        self._emit_s = emit_s
        self._user = user
        self._servers_m = server_positions_m(scenario)
        duration_s = float(emit_s[-1]) if len(emit_s) else 0.0
        children = phase_seed_sequence(seed, f"{phase}:mobility").spawn(users)
        self.routes: tuple[Route, ...] = tuple(
            phase_route(plan, scenario, duration_s, np.random.default_rng(child)) for child in children)

    def positions_m(self, first: int, count: int) -> np.ndarray:
        """Where requests ``first .. first + count - 1`` are sent from, shape (count, 2)."""
        at_s = self._emit_s[first:first + count]
        users = self._user[first:first + count]
        positions = np.empty((len(at_s), 2))
        for user in np.unique(users).tolist():
            mine = users == user
            positions[mine] = positions_at_m(self.plan, self.routes[user], at_s[mine])
        return positions

    def links(self, first: int, rtt_quantiles: np.ndarray, extra_propagation_s: np.ndarray,
              rtt_fraction: float) -> tuple[np.ndarray, Movement]:
        """Each (request, server) RTT and the requests' movement, for the requests from
        ``first`` on, one per row of ``rtt_quantiles`` (``edge.movement.links_at``)."""
        user_m = self.positions_m(first, rtt_quantiles.shape[0])
        return links_at(self.plan, self._inputs, user_m, self._servers_m, rtt_quantiles, extra_propagation_s,
                        rtt_fraction)
