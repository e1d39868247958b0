"""ω^t as a Gymnasium space, shared by both environments (``sim.env`` over the single-user
world, ``contention.env`` over the contention world): the same observation, the same spaces."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.safetail.spaces import StateScales, encode_state, state_dim

#: ``"dict"``: ω^t field by field; ``"vector"``: SafeTail's scaled state vector.
OBSERVATION_KINDS = ("dict", "vector")
_PER_SERVER = ("server_uplink_bps", "server_downlink_bps", "server_memory_util", "server_cpu_util",
               "server_active_users", "server_median_propagation_s", "server_max_load", "server_condition")
_SCALARS = ("input_bytes", "est_output_bytes", "user_uplink_bps", "user_downlink_bps")
_FRACTIONS = ("server_memory_util", "server_cpu_util")


def observation_space(kind: str, n_servers: int, n_gamma: int, n_location: int) -> spaces.Space[Any]:
    """SafeTail's state vector (``kind="vector"``), or ω^t field by field, float32: per-server
    arrays of shape (n,), scalars of shape (1,), ``gamma`` only when the use case has Γ."""
    if kind == "vector":
        return spaces.Box(-np.inf, np.inf, (state_dim(n_servers, n_gamma, n_location),), np.float32)
    fields: dict[str, spaces.Space[Any]] = {}
    for name in _PER_SERVER:
        fields[name] = spaces.Box(0.0, 1.0 if name in _FRACTIONS else np.inf, (n_servers,), np.float32)
    for name in _SCALARS:
        fields[name] = spaces.Box(0.0, np.inf, (1,), np.float32)
    if n_gamma:
        fields["gamma"] = spaces.Box(0.0, np.inf, (n_gamma,), np.float32)
    fields["user_location"] = spaces.Box(-np.inf, np.inf, (n_location,), np.float32)
    return spaces.Dict(fields)


def encode_observation(space: spaces.Space[Any], observation: Observation, scales: StateScales) -> Any:
    """``observation`` as an element of ``space`` (one of :func:`observation_space`'s)."""
    if isinstance(space, spaces.Box):
        return encode_state(observation, scales)
    assert isinstance(space, spaces.Dict)
    return {name: np.asarray(getattr(observation, name), dtype=np.float32).reshape(-1) for name in space.keys()}
