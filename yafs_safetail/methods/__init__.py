"""Methods: what decides where a request's copies go.

:class:`Policy` is the protocol every method implements (SafeTail, the baselines, a user's own);
``registry`` holds the method names; ``safetail`` is the learner of §III. Importing this package
loads nothing heavy: its names are imported on first access, so that a light module below it
(``objectives``, which the commands' parsers ask) loads without NumPy.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from yafs_safetail.settings.experiment import USER_METHODS, expand_method_spec

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


def _user_methods(specs: Sequence[str]) -> tuple[Any, ...]:
    """``--method`` specs as users' policies (``registry.UserMethod``: each file loaded and its
    class checked, so a bad one is one line before anything runs)."""
    from yafs_safetail.methods.registry import UserMethod  # NumPy: only once the options are parsed

    return tuple(UserMethod(expand_method_spec(spec)) for spec in specs)


# The run's declaration (settings.experiment.Task.methods) converts its specs with this, which
# only this floor can provide: every command that reads --method imports this package first.
USER_METHODS.provide(_user_methods)


def __getattr__(name: str) -> Any:
    module_name = _LAZY.get(name)
    if module_name is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module_name), name)
