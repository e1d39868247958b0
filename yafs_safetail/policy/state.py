"""Encoding of ω^t (Definition 1) into the FNN's input vector.

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
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from yafs_safetail.edge.observation import Observation

SERVER_FEATURES = (
    "uplink_bps",
    "downlink_bps",
    "memory_util",
    "cpu_util",
    "active_users",
    "median_propagation_s",
)

# Reference sizes, only there to bring the size features to O(1). Input: COCO val2017 images
# average about 160 KB (UC1, UC2); a 5 s clip of 16-bit 16 kHz audio is 160 KB (UC3).
# Estimated output: a few KB of detections (UC1), masks at about 0.4 of the image (UC2), the
# denoised clip at the input's size (UC3).
_USE_CASE_BYTES = {1: (160e3, 4e3), 2: (160e3, 64e3), 3: (160e3, 160e3)}
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
        location: Reference for each location coordinate (topology units).
    """

    input_bytes: float
    output_bytes: float
    gamma: tuple[float, ...] = ()
    bandwidth_bps: float = 20e6
    active_users: float = 4.0
    propagation_s: float = 1.0
    location: float = 1.0

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

        if use_case not in _USE_CASE_BYTES or use_case not in USE_CASES:
            raise ValueError(f"use_case must be one of {sorted(_USE_CASE_BYTES)}, got {use_case!r}")
        input_bytes, output_bytes = _USE_CASE_BYTES[use_case]
        columns = USE_CASES[use_case].gamma_columns
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
    )
