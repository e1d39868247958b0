"""The placement JSON and the scenario: topology + placement, checked against each other.

The placement JSON is YAFS's (``initialAllocation``), with one entry per edge server for the
service module; its order of edge servers is the server index order used everywhere
(Observation arrays, subsets, results).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

# The default files, named here as before (defaults.py: --help shows them before numpy loads).
from yafs_safetail.defaults import DATA_ROOT
from yafs_safetail.defaults import DEFAULT_PLACEMENT as DEFAULT_PLACEMENT
from yafs_safetail.defaults import DEFAULT_TOPOLOGY as DEFAULT_TOPOLOGY
from yafs_safetail.defaults import default_placement as default_placement
from yafs_safetail.edge.topology_io import (
    CONDITION_KEY,
    LOAD_DEVICE_KEY,
    REFERENCE_SERVER_IPT,
    EdgeTopology,
    JsonSource,
    ScenarioError,
    _is_node_id,
    _read_json,
    load_topology,
)

#: The folder of the default files (topologies/, placements/, traces/): the project checkout, or
#: the installed package's copy (defaults.DATA_ROOT). Paths inside it are recorded relative to it.
REPOSITORY = DATA_ROOT


@dataclass(frozen=True)
class EdgePlacementSpec:
    """The validated content of a placement file.

    Attributes:
        source: file name (or ``<placement dict>``) for messages.
        data: the raw YAFS placement JSON.
        app_name: the application every entry deploys.
        module_name: the service module every entry deploys.
        server_nodes: the nodes hosting the service, in file order (= server index order).
    """

    source: str
    data: dict[str, Any]
    app_name: str
    module_name: str
    server_nodes: tuple[int | str, ...]


def load_placement(source: JsonSource) -> EdgePlacementSpec:
    """Reads and validates a placement JSON (one service module on each edge server).

    Raises:
        ScenarioError: missing file, bad JSON, or a malformed entry.
    """
    data, name = _read_json(source, "placement")
    entries = data.get("initialAllocation")
    if not isinstance(entries, list) or not entries:
        raise ScenarioError(name, "initialAllocation", "missing or empty list")
    app_names: set[str] = set()
    module_names: set[str] = set()
    nodes: list[int | str] = []
    for index, entry in enumerate(entries):
        where = f"initialAllocation[{index}]"
        if not isinstance(entry, dict):
            raise ScenarioError(name, where, "expected an object")
        for key in ("module_name", "app"):
            if not isinstance(entry.get(key), str) or not entry[key]:
                raise ScenarioError(name, f"{where}.{key}", "missing or not a non-empty string")
        node = entry.get("id_resource")
        if not _is_node_id(node):
            raise ScenarioError(name, f"{where}.id_resource", f"not a node id: {node!r}")
        if node in nodes:
            raise ScenarioError(name, f"{where}.id_resource", f"node {node!r} listed twice")
        app_names.add(entry["app"])
        module_names.add(entry["module_name"])
        nodes.append(node)
    if len(app_names) != 1 or len(module_names) != 1:
        raise ScenarioError(
            name,
            "initialAllocation",
            "every entry must deploy the same app and module (the edge service); "
            f"found apps {sorted(app_names)} and modules {sorted(module_names)}",
        )
    return EdgePlacementSpec(
        source=name,
        data=data,
        app_name=app_names.pop(),
        module_name=module_names.pop(),
        server_nodes=tuple(nodes),
    )


@dataclass(frozen=True)
class EdgeScenario:
    """A topology and its placement, checked against each other and against the traces.

    Attributes:
        topology: the validated topology.
        placement: the validated placement.
        server_nodes: edge server node ids in server index order (placement order).
        server_conditions: distance condition per server index.
        server_load_devices: load-trace device per server index.
    """

    topology: EdgeTopology
    placement: EdgePlacementSpec
    server_nodes: tuple[int | str, ...]
    server_conditions: tuple[int, ...]
    server_load_devices: tuple[int, ...]

    @property
    def server_link_bandwidth_bps(self) -> tuple[float, ...]:
        """Bandwidth (bits/s) of each server's access-point link, per server index."""
        return tuple(self.topology.server_link_bandwidth_bps[node] for node in self.server_nodes)

    @property
    def server_link_pr_s(self) -> tuple[float, ...]:
        """PR (s) of each server's access-point link, per server index."""
        return tuple(self.topology.server_link_pr_s[node] for node in self.server_nodes)

    @property
    def server_ipt(self) -> tuple[float, ...]:
        """Each server's YAFS IPT, per server index."""
        return tuple(self.topology.server_ipt.get(node, REFERENCE_SERVER_IPT) for node in self.server_nodes)

    def server_capacity(self, default: int) -> tuple[int, ...]:
        """Each server's ``capacity`` per server index (``default`` where the file has none)."""
        values = (self.topology.server_capacity.get(node) for node in self.server_nodes)
        return tuple(default if value is None else value for value in values)

    @property
    def user_link_bandwidth_bps(self) -> float:
        """Bandwidth (bits/s) of the user's access-point link."""
        return self.topology.user_link_bandwidth_bps

    @property
    def user_link_pr_s(self) -> float:
        """PR (s) of the user's access-point link."""
        return self.topology.user_link_pr_s

    @property
    def n_servers(self) -> int:
        return len(self.server_nodes)

    @property
    def user_node(self) -> int | str:
        return self.topology.user_node

    @property
    def access_point_node(self) -> int | str:
        return self.topology.access_point_node

    @property
    def user_location(self) -> np.ndarray:
        return np.asarray(self.topology.user_location, dtype=float)

    @property
    def app_name(self) -> str:
        return self.placement.app_name

    @property
    def module_name(self) -> str:
        return self.placement.module_name


def build_scenario(
    topology: EdgeTopology,
    placement: EdgePlacementSpec,
    known_conditions: Iterable[int] | None = None,
    n_load_devices: int | None = None,
) -> EdgeScenario:
    """Checks a placement against its topology (and optionally the traces).

    Args:
        topology: from :func:`load_topology`.
        placement: from :func:`load_placement`.
        known_conditions: the distance conditions the propagation trace has; None skips
            the check.
        n_load_devices: number of devices in the load trace; None skips the check.

    Raises:
        ScenarioError: a placement node that is not an edge server, an edge server without
            the service, an unknown condition or load device.
    """
    servers = set(topology.edge_server_nodes)
    for index, node in enumerate(placement.server_nodes):
        if node not in servers:
            raise ScenarioError(
                placement.source,
                f"initialAllocation[{index}].id_resource",
                f"node {node!r} is not an edge_server of {topology.source}",
            )
    missing = [node for node in topology.edge_server_nodes if node not in placement.server_nodes]
    if missing:
        raise ScenarioError(
            placement.source,
            "initialAllocation",
            f"{len(placement.server_nodes)} servers placed but {topology.source} has "
            f"{len(servers)} edge servers (missing {missing})",
        )
    conditions = tuple(topology.conditions[node] for node in placement.server_nodes)
    if known_conditions is not None:
        allowed = sorted(set(int(c) for c in known_conditions))
        for node, condition in zip(placement.server_nodes, conditions, strict=True):
            if condition not in allowed:
                raise ScenarioError(
                    topology.source,
                    f"link to edge server {node!r}.{CONDITION_KEY}",
                    f"unknown distance condition {condition}; the propagation trace has {allowed}",
                )
    devices = []
    for index, node in enumerate(placement.server_nodes):
        device = topology.load_devices[node]
        device = index if device is None else device
        if n_load_devices is not None and device >= n_load_devices:
            raise ScenarioError(
                topology.source,
                f"edge server {node!r}.{LOAD_DEVICE_KEY}",
                f"unknown load device {device}; the load trace has devices 0..{n_load_devices - 1}",
            )
        devices.append(device)
    return EdgeScenario(
        topology=topology,
        placement=placement,
        server_nodes=placement.server_nodes,
        server_conditions=conditions,
        server_load_devices=tuple(devices),
    )


def load_scenario(
    topology_source: JsonSource,
    placement_source: JsonSource,
    known_conditions: Iterable[int] | None = None,
    n_load_devices: int | None = None,
) -> EdgeScenario:
    """Reads a topology and a placement and checks them together (see :func:`build_scenario`)."""
    return build_scenario(
        load_topology(topology_source),
        load_placement(placement_source),
        known_conditions=known_conditions,
        n_load_devices=n_load_devices,
    )
