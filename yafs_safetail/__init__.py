"""yafs-safetail: SafeTail learned redundant edge dispatch on a YAFS-compatible simulator.

Importing the package makes the Gymnasium environments ``yafs_safetail/SafeTail-v0``
(``yafs_safetail.sim.env``) and ``yafs_safetail/SafeTailContention-v0``
(``yafs_safetail.contention.env``) available to ``gymnasium.make`` (an environment's module
itself loads on ``gymnasium.make``). The package does not import Gymnasium itself: the command line answers
``--help`` and argument errors without loading NumPy or Gymnasium. The ids are registered as soon
as Gymnasium's registry exists, whether it was imported before this package or after.

Importing the package also pins TensorFlow's numerical path (``numerics``): the same seed gives
the same files on every x86-64 processor.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from types import ModuleType
from typing import Any

from yafs_safetail.numerics import pin_numerical_path

# Before anything of the package can load TensorFlow: one numerical path on every x86-64.
pin_numerical_path()

__version__ = "0.1.0"

ENV_ID = "yafs_safetail/SafeTail-v0"
CONTENTION_ENV_ID = "yafs_safetail/SafeTailContention-v0"
_ENTRY_POINTS = {ENV_ID: "yafs_safetail.sim.env:SafeTailEnv",
                 CONTENTION_ENV_ID: "yafs_safetail.contention.env:ContentionEnv"}
_REGISTRY_MODULE = "gymnasium.envs.registration"


def _register(registration: ModuleType) -> None:
    for env_id, entry_point in _ENTRY_POINTS.items():
        if env_id not in registration.registry:
            registration.register(id=env_id, entry_point=entry_point)


class _RegisterWhenGymnasiumLoads(importlib.abc.MetaPathFinder):
    """Registers the ids right after Gymnasium's registry module first executes.

    Asked only for that one module name; it lets the normal finders locate the module and wraps
    the loader's ``exec_module`` so the registration follows it. It then leaves ``sys.meta_path``.
    """

    registers = ENV_ID  # a marker that survives importlib.reload (a new class object)

    def find_spec(self, fullname: str, path: Any, target: ModuleType | None = None
                  ) -> importlib.machinery.ModuleSpec | None:
        if fullname != _REGISTRY_MODULE:
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        execute = loader.exec_module

        def exec_module_then_register(module: ModuleType) -> None:
            execute(module)
            _register(module)

        loader.exec_module = exec_module_then_register  # type: ignore[method-assign]
        return spec


if _REGISTRY_MODULE in sys.modules:
    _register(sys.modules[_REGISTRY_MODULE])
elif not any(getattr(finder, "registers", None) == ENV_ID for finder in sys.meta_path):
    sys.meta_path.insert(0, _RegisterWhenGymnasiumLoads())
