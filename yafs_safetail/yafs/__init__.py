"""Clean-room YAFS3-compatible simulation core.

Port a YAFS3 script by changing its imports only: ``from yafs.core import Sim`` becomes
``from yafs_safetail.yafs.core import Sim`` (or ``import yafs_safetail.yafs as yafs``).
Module and class names follow YAFS3: ``core.Sim``, ``topology.Topology``,
``application.Application``/``Message``, ``selection.Selection``, ``placement``,
``population``, ``distribution``, ``path_routing``, ``metrics``, ``stats``, ``action``; the
additions are ``hooks`` (pluggable delays), ``outcomes`` (redundant-dispatch results),
``analysis`` (pandas helpers) and ``errors``. See docs/core.md.
"""

from __future__ import annotations

import importlib
from typing import Any

from yafs_safetail.yafs import (
    action,
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
from yafs_safetail.yafs.distribution import (
    Distribution,
    deterministic_distribution,
    deterministicDistributionStartPoint,
    exponential_distribution,
    exponentialDistribution,
    exponentialDistributionStartPoint,
    uniformDistribution,
)
from yafs_safetail.yafs.errors import YAFSInputError
from yafs_safetail.yafs.metrics import Metrics
from yafs_safetail.yafs.outcomes import CopyOutcome, RequestOutcome
from yafs_safetail.yafs.placement import ClusterPlacement, Placement
from yafs_safetail.yafs.population import Population, Statical
from yafs_safetail.yafs.selection import First_ShortestPath, OneRandomPath, Selection
from yafs_safetail.yafs.topology import Topology

__all__ = [
    "Application",
    "ClusterPlacement",
    "CopyOutcome",
    "Distribution",
    "First_ShortestPath",
    "Message",
    "Metrics",
    "OneRandomPath",
    "Placement",
    "Population",
    "RequestOutcome",
    "Selection",
    "Sim",
    "Statical",
    "Topology",
    "YAFSInputError",
    "action",
    "application",
    "core",
    "create_applications_from_json",
    "deterministicDistributionStartPoint",
    "deterministic_distribution",
    "distribution",
    "errors",
    "exponentialDistribution",
    "exponentialDistributionStartPoint",
    "exponential_distribution",
    "hooks",
    "metrics",
    "outcomes",
    "path_routing",
    "placement",
    "population",
    "selection",
    "topology",
    "uniformDistribution",
]

_LAZY = {"stats", "analysis"}  # pandas-backed; imported on first use


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return importlib.import_module(f"yafs_safetail.yafs.{name}")
    raise AttributeError(f"module 'yafs_safetail.yafs' has no attribute {name!r}")
