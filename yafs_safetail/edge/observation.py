"""The state ω^t of the paper's Definition 1, as the policy sees it.

Units are SI throughout: seconds, bytes, bits per second; utilisations are fractions in [0, 1].
Server arrays are indexed by server index 0..n-1, which is the order of the servers in the
edge model (the placement JSON's order of edge servers).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass(frozen=True, slots=True, eq=False)
class Observation:
    """ω^t = (Ω_1..Ω_n, P_j, U) at the moment a request is issued.

    Attributes:
        server_uplink_bps: λ^u_i, each server's uplink bandwidth available to this user, shape (n,).
        server_downlink_bps: λ^d_i, each server's downlink bandwidth, shape (n,).
        server_memory_util: M_i, memory utilisation in [0, 1], shape (n,).
        server_cpu_util: U_i (the paper's calligraphic U), CPU utilisation in [0, 1], shape (n,).
        server_active_users: ℓ_i, users currently running on each server, shape (n,), integers.
        server_median_propagation_s: ρ^μ_i(L), median propagation latency user -> server, shape (n,).
        input_bytes: Size(I_j), the request's input size.
        est_output_bytes: eSize(O_j), the estimated output size.
        gamma: Γ_j, the request's input traits that drive compute time (use-case specific,
            possibly empty; the number of parallel processes is a server property and is
            carried by ``server_active_users``).
        user_location: L, the user's coordinates from the topology (zeros when absent).
        user_uplink_bps: Λ^u.
        user_downlink_bps: Λ^d.
        server_max_load: each server's load limit: a server with this many active users
            refuses a copy, shape (n,), integers (Table I: 4 everywhere).
        server_condition: each link's condition now, 1 (near) to 5 (far), whose pool ρ^μ_i is
            the median of, shape (n,), integers: the topology's, or, for a user who moves, the
            one its distance gives (docs/mobility.md). Not in the paper's state (SafeTail's
            network reads ρ^μ_i); None only where a caller builds an observation by hand.
        step: the request's index in its phase (to tell requests apart; not part of ω^t and
            not in the Gymnasium observation).
    """

    server_uplink_bps: np.ndarray
    server_downlink_bps: np.ndarray
    server_memory_util: np.ndarray
    server_cpu_util: np.ndarray
    server_active_users: np.ndarray
    server_median_propagation_s: np.ndarray
    input_bytes: float
    est_output_bytes: float
    gamma: np.ndarray
    user_location: np.ndarray
    user_uplink_bps: float
    user_downlink_bps: float
    server_max_load: np.ndarray
    step: int = -1
    server_condition: np.ndarray | None = None

    def __eq__(self, other: object) -> bool:
        # Field by field, arrays by value (the generated __eq__ would compare arrays
        # element-wise and fail on their truth value).
        if not isinstance(other, Observation):
            return NotImplemented
        return all(np.array_equal(getattr(self, f.name), getattr(other, f.name))
                   for f in fields(Observation))

    __hash__ = None  # type: ignore[assignment]  # mutable arrays inside

    @property
    def n_servers(self) -> int:
        return int(self.server_active_users.shape[0])
