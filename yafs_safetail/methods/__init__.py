"""Methods: what decides where a request's copies go.

:class:`Policy` is the protocol every method implements (SafeTail, the baselines, a user's own);
``registry`` holds the method names; ``safetail`` is the learner of §III. Importing this package
loads nothing heavy: its names are imported on first access, so that a light module below it
(``objectives``, which the commands' parsers ask) loads without NumPy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from yafs_safetail.methods.baselines import MinLoadX, MinPropX, Oracle, RandX
    from yafs_safetail.methods.policy import Policy, PolicyError
    from yafs_safetail.methods.registry import make_baseline

__all__ = ["MinLoadX", "MinPropX", "Oracle", "Policy", "PolicyError", "RandX", "make_baseline"]

_LAZY = {
    "MinLoadX": "yafs_safetail.methods.baselines",
    "MinPropX": "yafs_safetail.methods.baselines",
    "Oracle": "yafs_safetail.methods.baselines",
    "RandX": "yafs_safetail.methods.baselines",
    "Policy": "yafs_safetail.methods.policy",
    "PolicyError": "yafs_safetail.methods.policy",
    "make_baseline": "yafs_safetail.methods.registry",
}


def __getattr__(name: str) -> Any:
    module_name = _LAZY.get(name)
    if module_name is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module_name), name)
