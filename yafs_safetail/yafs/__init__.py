"""Clean-room YAFS3-compatible simulation core.

Port a YAFS3 script by changing its imports only: ``from yafs.core import Sim`` becomes
``from yafs_safetail.yafs.core import Sim`` (or ``import yafs_safetail.yafs as yafs``).
Module and class names follow YAFS3: ``core.Sim``, ``topology.Topology``,
``application.Application``/``Message``, ``selection.Selection``, ``placement``,
``population``, ``distribution``, ``path_routing``, ``metrics``, ``stats``; the additions are
``hooks`` (pluggable delays), ``outcomes`` (redundant-dispatch results), ``analysis``
(pandas helpers) and ``errors``. See docs/core.md.
"""

from __future__ import annotations

import importlib
from typing import Any

from yafs_safetail.yafs import (
    application,
    core,
    distribution,
    errors,
    hooks,
    metrics,
    outcomes,
    path_routing,
    placement,
    population,
    selection,
    topology,
)
from yafs_safetail.yafs.application import Application, Message, create_applications_from_json
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.errors import YAFSInputError
from yafs_safetail.yafs.outcomes import CopyOutcome, RequestOutcome
from yafs_safetail.yafs.selection import Selection
from yafs_safetail.yafs.topology import Topology

__all__ = [
    "Application",
    "CopyOutcome",
    "Message",
    "RequestOutcome",
    "Selection",
    "Sim",
    "Topology",
    "YAFSInputError",
    "application",
    "core",
    "create_applications_from_json",
    "distribution",
    "errors",
    "hooks",
    "metrics",
    "outcomes",
    "path_routing",
    "placement",
    "population",
    "selection",
    "topology",
]

_LAZY = {"stats", "analysis"}  # pandas-backed; imported on first use


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return importlib.import_module(f"yafs_safetail.yafs.{name}")
    raise AttributeError(f"module 'yafs_safetail.yafs' has no attribute {name!r}")
