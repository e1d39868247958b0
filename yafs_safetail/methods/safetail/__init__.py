"""The SafeTail learner (§III): actions, reward, target vector, state encoding, FNN, presets.

The pure functions import without TensorFlow; the network and learner (which need Keras) are
loaded on first access so that importing this package stays cheap.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from yafs_safetail.methods.safetail.learner import target_vector
from yafs_safetail.methods.safetail.reward import reward
from yafs_safetail.methods.safetail.spaces import (
    MAX_SERVERS,
    StateScales,
    action_of,
    encode_state,
    n_actions,
    state_dim,
    state_feature_names,
    subset_of,
)

if TYPE_CHECKING:
    from yafs_safetail.methods.safetail.learner import SafeTailLearner

__all__ = [
    "MAX_SERVERS",
    "SafeTailLearner",
    "StateScales",
    "action_of",
    "encode_state",
    "n_actions",
    "reward",
    "state_dim",
    "state_feature_names",
    "subset_of",
    "target_vector",
]

_LAZY = {"SafeTailLearner": "yafs_safetail.methods.safetail.learner"}


def __getattr__(name: str) -> Any:
    module_name = _LAZY.get(name)
    if module_name is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module_name), name)
