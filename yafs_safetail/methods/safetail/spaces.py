"""SafeTail's spaces: the state vector the FNN reads and the actions it chooses from.

## Actions

The 2^n - 1 actions of §III and the non-empty server subsets they stand for.

Mapping: action ``a`` (0 <= a <= 2^n - 2) is the bitmask ``a + 1``; server ``i`` (0-based, the
edge model's server order) is in the subset iff bit ``i`` of ``a + 1`` is set. So for n = 3:
action 0 = (0,), 1 = (1,), 2 = (0, 1), 3 = (2,), 4 = (0, 2), 5 = (1, 2), 6 = (0, 1, 2).
The full set is always the last action, ``2^n - 2``.

## State

Encoding of ω^t (Definition 1) into the FNN's input vector.

Layout (float32), for n servers, g entries of Γ and d location coordinates:

* per server i = 0..n-1, six consecutive entries (Ω_i):
  uplink bps, downlink bps, memory utilisation, CPU utilisation, active users,
  median propagation s;
* then P_j: input bytes, estimated output bytes, Γ (g entries);
* then U: location (d entries), user uplink bps, user downlink bps.

Length 6n + 2 + g + d + 2. Every entry is divided by a fixed reference scale (:class:`StateScales`)
so that typical values are of order 1; utilisations are already fractions and are kept as is.
The paper is silent on normalisation; docs/policy.md lists the reference values.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from yafs_safetail.edge.observation import Observation

MAX_SERVERS = 10
"""Largest n supported (paper assumption iii: fewer than 10 reachable servers)."""


def _check_n_servers(n_servers: int) -> int:
    if isinstance(n_servers, bool) or not isinstance(n_servers, int | np.integer):
        raise ValueError(f"n_servers must be an integer, got {n_servers!r}")
    n = int(n_servers)
    if not 1 <= n <= MAX_SERVERS:
        raise ValueError(f"n_servers must be in 1..{MAX_SERVERS}, got {n}")
    return n


def n_actions(n_servers: int) -> int:
    """Number of actions (non-empty subsets) for ``n_servers`` servers: 2^n - 1.

    Raises:
        ValueError: ``n_servers`` is not an integer in 1..10.
    """
    return (1 << _check_n_servers(n_servers)) - 1


@lru_cache(maxsize=MAX_SERVERS)
def _subset_table(n: int) -> tuple[tuple[int, ...], ...]:
    return tuple(
        tuple(i for i in range(n) if (mask >> i) & 1) for mask in range(1, 1 << n)
    )


@lru_cache(maxsize=MAX_SERVERS)
def subset_matrix(n_servers: int) -> np.ndarray:
    """Boolean matrix ``M[a, b]``: the subset of action ``b`` is contained in that of ``a``.

    Read-only; shape (2^n - 1, 2^n - 1). Used by the target vector.
    """
    n = _check_n_servers(n_servers)
    masks = np.arange(1, 1 << n, dtype=np.int64)
    matrix = (masks[None, :] & ~masks[:, None]) == 0
    matrix.setflags(write=False)
    return matrix


@lru_cache(maxsize=MAX_SERVERS)
def membership_matrix(n_servers: int) -> np.ndarray:
    """float32 matrix ``M[a, i]`` = 1 when server ``i`` is in the subset of action ``a``, else 0.

    Read-only; shape (2^n - 1, n). ``M @ per_server`` sums a per-server quantity over every
    action's subset at once (the value learner's copy price).
    """
    n = _check_n_servers(n_servers)
    masks = np.arange(1, 1 << n, dtype=np.int64)
    matrix = ((masks[:, None] >> np.arange(n)[None, :]) & 1).astype(np.float32)
    matrix.setflags(write=False)
    return matrix


def subset_of(action_index: int, n_servers: int) -> tuple[int, ...]:
    """Server indices (ascending) of the subset that action ``action_index`` selects.

    Args:
        action_index: An action in 0..2^n - 2.
        n_servers: n, in 1..10.

    Returns:
        The non-empty tuple of 0-based server indices, ascending.

    Raises:
        ValueError: ``n_servers`` out of 1..10 or ``action_index`` not an integer in range.
    """
    n = _check_n_servers(n_servers)
    if isinstance(action_index, bool) or not isinstance(action_index, int | np.integer):
        raise ValueError(f"action_index must be an integer, got {action_index!r}")
    a = int(action_index)
    if not 0 <= a < (1 << n) - 1:
        raise ValueError(f"action_index must be in 0..{(1 << n) - 2} for n_servers={n}, got {a}")
    return _subset_table(n)[a]


def action_of(subset: Iterable[int], n_servers: int) -> int:
    """Action index of a non-empty subset of server indices (inverse of :func:`subset_of`).

    Args:
        subset: Distinct 0-based server indices, any order.
        n_servers: n, in 1..10.

    Returns:
        The action index in 0..2^n - 2.

    Raises:
        ValueError: empty subset, an index that is not an integer in 0..n-1, or a repeated index.
    """
    n = _check_n_servers(n_servers)
    mask = 0
    count = 0
    for server in subset:
        if isinstance(server, bool) or not isinstance(server, int | np.integer):
            raise ValueError(f"subset entries must be integer server indices, got {server!r}")
        i = int(server)
        if not 0 <= i < n:
            raise ValueError(f"server index {i} out of range 0..{n - 1}")
        if (mask >> i) & 1:
            raise ValueError(f"server index {i} repeated in subset")
        mask |= 1 << i
        count += 1
    if count == 0:
        raise ValueError("subset must be non-empty (the paper's actions exclude the empty set)")
    return mask - 1


SERVER_FEATURES = (
    "uplink_bps",
    "downlink_bps",
    "memory_util",
    "cpu_util",
    "active_users",
    "median_propagation_s",
)

# Reference per Γ column of edge/usecases.py (units of the column).
GAMMA_REFERENCES = {"file_bytes": 160e3, "duration_s": 5.0}


@dataclass(frozen=True, slots=True)
class StateScales:
    """Fixed reference scales (SI units) each state entry is divided by.

    Attributes:
        input_bytes: Reference for Size(I_j), bytes.
        output_bytes: Reference for eSize(O_j), bytes.
        gamma: One reference per Γ entry, in Γ's own units; its length must equal the
            observation's ``gamma`` length.
        bandwidth_bps: Reference for every bandwidth (servers' and user's); the original code's
            uncontended link, 20 Mbit/s.
        active_users: Reference for ℓ_i, the maximum load of a server (Table I: 4).
        propagation_s: Reference for ρ^μ_i; 1 s keeps seconds as they are.
        location: Reference for each location coordinate, metres on the topology's plane:
            100 m, about where the signal turns poor (``edge.signal``), brings a moving user's
            position to O(1) (every shipped topology's user at rest sits at the origin).
    """

    input_bytes: float
    output_bytes: float
    gamma: tuple[float, ...] = ()
    bandwidth_bps: float = 20e6
    active_users: float = 4.0
    propagation_s: float = 1.0
    location: float = 100.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "gamma", tuple(float(x) for x in self.gamma))
        for name in ("input_bytes", "output_bytes", "bandwidth_bps", "active_users",
                     "propagation_s", "location"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"StateScales.{name} must be finite and > 0, got {value!r}")
        for i, value in enumerate(self.gamma):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"StateScales.gamma[{i}] must be finite and > 0, got {value!r}")

    @classmethod
    def for_use_case(cls, use_case: int) -> StateScales:
        """Default scales for a use case (1, 2 or 3), Γ references following the use case's
        Γ columns in ``yafs_safetail.edge.usecases`` (UC1: none; UC2: file bytes; UC3: file
        bytes, duration s).

        Raises:
            ValueError: unknown use case, or a Γ column without a reference here.
        """
        from yafs_safetail.edge.usecases import USE_CASES

        if use_case not in USE_CASES:
            raise ValueError(f"use_case must be one of {sorted(USE_CASES)}, got {use_case!r}")
        definition = USE_CASES[use_case]
        # The use case's typical sizes, only there to bring the size features to O(1).
        input_bytes, output_bytes = definition.typical_input_bytes, definition.typical_output_bytes
        columns = definition.gamma_columns
        missing = [c for c in columns if c not in GAMMA_REFERENCES]
        if missing:
            raise ValueError(f"use case {use_case}: no state reference scale for Γ column(s) {missing}")
        return cls(input_bytes=input_bytes, output_bytes=output_bytes,
                   gamma=tuple(GAMMA_REFERENCES[c] for c in columns))


def state_dim(n_servers: int, n_gamma: int, n_location: int) -> int:
    """Length of the encoded state: 6n + 2 + g + d + 2."""
    return 6 * n_servers + 2 + n_gamma + n_location + 2


def state_feature_names(n_servers: int, n_gamma: int, n_location: int) -> list[str]:
    """Name of every entry of the encoded state, in order (for logs and documentation)."""
    names = [f"server{i}_{f}" for i in range(n_servers) for f in SERVER_FEATURES]
    names += ["input_bytes", "est_output_bytes"] + [f"gamma{k}" for k in range(n_gamma)]
    names += [f"location{k}" for k in range(n_location)]
    names += ["user_uplink_bps", "user_downlink_bps"]
    return names


@lru_cache(maxsize=64)
def _inverse_scales(scales: StateScales, n: int, g: int, d: int) -> np.ndarray:
    if g != len(scales.gamma):
        raise ValueError(
            f"observation has {g} Γ entries but StateScales.gamma has {len(scales.gamma)}"
        )
    per_server = [scales.bandwidth_bps, scales.bandwidth_bps, 1.0, 1.0, scales.active_users,
                  scales.propagation_s]
    ref = per_server * n + [scales.input_bytes, scales.output_bytes, *scales.gamma]
    ref += [scales.location] * d + [scales.bandwidth_bps, scales.bandwidth_bps]
    inverse = (1.0 / np.asarray(ref, dtype=np.float64)).astype(np.float32)
    inverse.setflags(write=False)
    return inverse


def encode_state(obs: Observation, scales: StateScales) -> np.ndarray:
    """Encode ω^t as the FNN input (layout in the module docstring).

    Args:
        obs: The observation at the moment the request is issued.
        scales: Reference scales; ``len(scales.gamma)`` must equal ``len(obs.gamma)``.

    Returns:
        A new float32 vector of length ``state_dim(n, g, d)``.

    Raises:
        ValueError: Γ length mismatch between the observation and the scales.
    """
    n = obs.server_uplink_bps.shape[0]
    g = obs.gamma.shape[0]
    d = obs.user_location.shape[0]
    inverse = _inverse_scales(scales, n, g, d)
    out = np.empty(inverse.shape[0], dtype=np.float32)
    six_n = 6 * n
    block = out[:six_n].reshape(n, 6)
    block[:, 0] = obs.server_uplink_bps
    block[:, 1] = obs.server_downlink_bps
    block[:, 2] = obs.server_memory_util
    block[:, 3] = obs.server_cpu_util
    block[:, 4] = obs.server_active_users
    block[:, 5] = obs.server_median_propagation_s
    out[six_n] = obs.input_bytes
    out[six_n + 1] = obs.est_output_bytes
    k = six_n + 2
    out[k:k + g] = obs.gamma
    k += g
    out[k:k + d] = obs.user_location
    out[k + d] = obs.user_uplink_bps
    out[k + d + 1] = obs.user_downlink_bps
    out *= inverse
    return out


def random_observation(rng: np.random.Generator, n_servers: int = 5) -> Observation:
    """A plausible random ω^t (UC1-like: no Γ) for benchmarks and synthetic learning checks.

    Bandwidths 2-20 Mbit/s, 0-4 active users, median propagation 30-700 ms, inputs of
    50-300 kB: the ranges of the shipped traces, drawn uniformly from ``rng``.
    """
    n = n_servers
    return Observation(
        server_uplink_bps=rng.uniform(2e6, 20e6, n),
        server_downlink_bps=rng.uniform(2e6, 20e6, n),
        server_memory_util=rng.uniform(0.0, 1.0, n),
        server_cpu_util=rng.uniform(0.0, 1.0, n),
        server_active_users=rng.integers(0, 5, n),
        server_median_propagation_s=rng.uniform(0.03, 0.7, n),
        input_bytes=rng.uniform(50e3, 300e3),
        est_output_bytes=rng.uniform(1e3, 8e3),
        gamma=np.empty(0),
        user_location=rng.uniform(-1.0, 1.0, 2),
        user_uplink_bps=rng.uniform(5e6, 20e6),
        user_downlink_bps=rng.uniform(5e6, 20e6),
        server_max_load=np.full(n, 4),
    )
