"""Reading the topology and placement JSON files users edit, with validation.

A SafeTail topology is a YAFS topology JSON (``entity`` + ``link``) with a few extra keys
that YAFS itself ignores:

* every entity has ``"type"``: ``"user"`` (exactly one), ``"access_point"`` (exactly one) or
  ``"edge_server"`` (one or more); the user may carry ``"x"``, ``"y"`` (its location L);
  an edge server may carry ``"load_device"``, the load-trace device that drives its
  background users (default: the server's index);
* the user is linked to the access point, and every edge server is linked to the access
  point by a link carrying ``"condition"``, the distance condition (1..5) whose propagation
  pool the server's RTTs are drawn from;
* every link keeps YAFS's ``"BW"`` and ``"PR"`` so YAFS's own delay formula still works.

The placement JSON is YAFS's (``initialAllocation``), with one entry per edge server for the
service module; its order of edge servers is the server index order used everywhere
(Observation arrays, subsets, results).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

USER_TYPE = "user"
ACCESS_POINT_TYPE = "access_point"
EDGE_SERVER_TYPE = "edge_server"
CONDITION_KEY = "condition"
LOAD_DEVICE_KEY = "load_device"


class ScenarioError(ValueError):
    """A topology or placement file is missing or does not describe a valid edge scenario.

    The message is one line: ``<file>: <entry/field>: <what is wrong>``.
    """

    def __init__(self, source: str, field: str, problem: str) -> None:
        super().__init__(f"{source}: {field}: {problem}")
        self.source = source
        self.field = field
        self.problem = problem


JsonSource = str | Path | Mapping[str, Any]


def _read_json(source: JsonSource, what: str) -> tuple[dict[str, Any], str]:
    """Returns the parsed JSON and a name for error messages."""
    if isinstance(source, Mapping):
        return dict(source), f"<{what} dict>"
    path = Path(source)
    name = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(name, "file", f"{what} file not found") from None
    except OSError as exc:
        raise ScenarioError(name, "file", f"cannot read {what} file ({exc.strerror})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ScenarioError(name, f"line {exc.lineno}", f"invalid JSON ({exc.msg})") from None
    if not isinstance(data, dict):
        raise ScenarioError(name, "top level", "expected a JSON object")
    return data, name


def _is_number(value: Any) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _is_node_id(value: Any) -> bool:
    return (isinstance(value, int) and not isinstance(value, bool)) or isinstance(value, str)


@dataclass(frozen=True)
class EdgeTopology:
    """The validated content of a SafeTail topology file.

    Attributes:
        source: file name (or ``<topology dict>``) for messages.
        data: the raw YAFS topology JSON, to hand to the core's ``Topology.load``.
        user_node: the user's node id.
        access_point_node: the access point's node id.
        edge_server_nodes: edge server node ids in file order.
        conditions: distance condition per edge server node.
        load_devices: load-trace device per edge server node, or None (default: index).
        user_location: (x, y) of the user; zeros when absent.
        user_link_bw: BW of the user–access point link (Mbit/s, YAFS's unit).
        user_link_pr: PR of the user–access point link (s).
        server_link_bw: BW of each access point–server link, per edge server node (Mbit/s).
        server_link_pr: PR of each access point–server link, per edge server node (s).
    """

    source: str
    data: dict[str, Any]
    user_node: int | str
    access_point_node: int | str
    edge_server_nodes: tuple[int | str, ...]
    conditions: dict[int | str, int]
    load_devices: dict[int | str, int | None]
    user_location: tuple[float, float]
    user_link_bw: float
    user_link_pr: float
    server_link_bw: dict[int | str, float]
    server_link_pr: dict[int | str, float]


def load_topology(source: JsonSource) -> EdgeTopology:
    """Reads and validates a SafeTail topology JSON.

    Args:
        source: a path to the JSON file or the already-parsed dict.

    Returns:
        The validated topology.

    Raises:
        ScenarioError: missing file, bad JSON, or a structural problem (named entry/field).
    """
    data, name = _read_json(source, "topology")
    entities = data.get("entity")
    links = data.get("link")
    if not isinstance(entities, list) or not entities:
        raise ScenarioError(name, "entity", "missing or empty list of entities")
    if not isinstance(links, list) or not links:
        raise ScenarioError(name, "link", "missing or empty list of links")

    types: dict[int | str, str] = {}
    user_location = (0.0, 0.0)
    load_devices: dict[int | str, int | None] = {}
    server_order: list[int | str] = []
    for index, entity in enumerate(entities):
        where = f"entity[{index}]"
        if not isinstance(entity, dict):
            raise ScenarioError(name, where, "expected an object")
        node = entity.get("id")
        if not _is_node_id(node):
            raise ScenarioError(name, f"{where}.id", "missing or not an integer/string node id")
        if node in types:
            raise ScenarioError(name, f"{where}.id", f"duplicate node id {node!r}")
        kind = entity.get("type")
        if kind not in (USER_TYPE, ACCESS_POINT_TYPE, EDGE_SERVER_TYPE):
            raise ScenarioError(
                name,
                f"{where}.type",
                f"got {kind!r}; expected one of {USER_TYPE!r}, {ACCESS_POINT_TYPE!r}, "
                f"{EDGE_SERVER_TYPE!r}",
            )
        types[node] = kind
        if kind == USER_TYPE:
            coords = []
            for key in ("x", "y"):
                value = entity.get(key, 0.0)
                if not _is_number(value):
                    raise ScenarioError(name, f"{where}.{key}", f"not a finite number: {value!r}")
                coords.append(float(value))
            user_location = (coords[0], coords[1])
        if kind == EDGE_SERVER_TYPE:
            device = entity.get(LOAD_DEVICE_KEY)
            if device is not None and (
                not isinstance(device, int) or isinstance(device, bool) or device < 0
            ):
                raise ScenarioError(
                    name, f"{where}.{LOAD_DEVICE_KEY}", f"not a non-negative integer: {device!r}"
                )
            load_devices[node] = device
            server_order.append(node)

    users = [node for node, kind in types.items() if kind == USER_TYPE]
    access_points = [node for node, kind in types.items() if kind == ACCESS_POINT_TYPE]
    if len(users) != 1:
        raise ScenarioError(name, "entity.type", f"expected exactly one 'user', found {len(users)}")
    if len(access_points) != 1:
        raise ScenarioError(
            name, "entity.type", f"expected exactly one 'access_point', found {len(access_points)}"
        )
    if not server_order:
        raise ScenarioError(name, "entity.type", "no 'edge_server' entity")
    user, access_point = users[0], access_points[0]

    conditions: dict[int | str, int] = {}
    server_link_bw: dict[int | str, float] = {}
    server_link_pr: dict[int | str, float] = {}
    user_link_bw = user_link_pr = None
    for index, link in enumerate(links):
        where = f"link[{index}]"
        if not isinstance(link, dict):
            raise ScenarioError(name, where, "expected an object")
        ends = (link.get("s"), link.get("d"))
        for key, node in zip(("s", "d"), ends, strict=True):
            if node not in types:
                raise ScenarioError(name, f"{where}.{key}", f"unknown node id {node!r}")
        for key in ("BW", "PR"):
            value = link.get(key)
            if not _is_number(value) or value < 0 or (key == "BW" and value == 0):
                raise ScenarioError(
                    name, f"{where}.{key}", f"missing or not a positive number: {value!r}"
                )
        pair = set(ends)
        if pair == {user, access_point}:
            user_link_bw, user_link_pr = float(link["BW"]), float(link["PR"])
            continue
        servers = [node for node in ends if types[node] == EDGE_SERVER_TYPE]
        if len(servers) != 1 or access_point not in pair:
            raise ScenarioError(
                name,
                where,
                "only user-access_point and access_point-edge_server links are supported",
            )
        server = servers[0]
        if server in conditions:
            raise ScenarioError(name, where, f"edge server {server!r} has a second link")
        condition = link.get(CONDITION_KEY)
        if not isinstance(condition, int) or isinstance(condition, bool):
            raise ScenarioError(
                name, f"{where}.{CONDITION_KEY}", f"missing or not an integer: {condition!r}"
            )
        conditions[server] = condition
        server_link_bw[server] = float(link["BW"])
        server_link_pr[server] = float(link["PR"])
    if user_link_bw is None:
        raise ScenarioError(name, "link", "no link between the user and the access point")
    for server in server_order:
        if server not in conditions:
            raise ScenarioError(
                name, "link", f"edge server {server!r} is not linked to the access point"
            )
    return EdgeTopology(
        source=name,
        data=data,
        user_node=user,
        access_point_node=access_point,
        edge_server_nodes=tuple(server_order),
        conditions=conditions,
        load_devices=load_devices,
        user_location=user_location,
        user_link_bw=user_link_bw,
        user_link_pr=user_link_pr,
        server_link_bw=server_link_bw,
        server_link_pr=server_link_pr,
    )


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
    def server_link_bw(self) -> tuple[float, ...]:
        """BW (Mbit/s) of each server's access-point link, per server index."""
        return tuple(self.topology.server_link_bw[node] for node in self.server_nodes)

    @property
    def server_link_pr(self) -> tuple[float, ...]:
        """PR (s) of each server's access-point link, per server index."""
        return tuple(self.topology.server_link_pr[node] for node in self.server_nodes)

    @property
    def user_link_bw(self) -> float:
        """BW (Mbit/s) of the user's access-point link."""
        return self.topology.user_link_bw

    @property
    def user_link_pr(self) -> float:
        """PR (s) of the user's access-point link."""
        return self.topology.user_link_pr

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
