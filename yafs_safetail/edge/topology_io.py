"""Reading the topology and placement JSON files users edit, with validation.

A SafeTail topology is a YAFS topology JSON (``entity`` + ``link``) with a few extra keys
that YAFS itself ignores:

* every entity has ``"type"``: ``"user"`` (exactly one), ``"access_point"`` (exactly one) or
  ``"edge_server"`` (one or more); the user may carry ``"x"``, ``"y"`` (its location L,
  metres); the user and the edge servers may carry positions, in metres (``"x"``, ``"y"``) or
  in degrees (``"lat"``, ``"lon"``), one of the two in a whole file, every server or none
  (``edge.positions``; a user who moves needs them, nothing else reads them);
  an edge server may carry ``"load_device"``, the load-trace device that drives its
  background users (default: the server's index), and, for the contention world
  (``yafs_safetail.contention``), ``"capacity"`` (copies it runs at once; default: the load
  limit) — its YAFS ``"IPT"`` then sets its speed relative to ``REFERENCE_SERVER_IPT``;
* the user is linked to the access point, and every edge server is linked to the access
  point by a link carrying ``"condition"``, the distance condition (1..5) whose propagation
  pool the server's RTTs are drawn from;
* every link keeps YAFS's ``"BW"`` and ``"PR"`` so YAFS's own delay formula still works.

The placement and the scenario that joins both are in ``edge.scenario``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeGuard

from yafs_safetail.edge.positions import (
    DEGREE_KEYS,
    METRE_KEYS,
    Origin,
    PositionError,
    check_degrees,
    project_m,
)

USER_TYPE = "user"
ACCESS_POINT_TYPE = "access_point"
EDGE_SERVER_TYPE = "edge_server"
CONDITION_KEY = "condition"
LOAD_DEVICE_KEY = "load_device"
CAPACITY_KEY = "capacity"
IPT_KEY = "IPT"
#: The IPT of the server the compute traces were measured on (the shipped topologies' value):
#: a server with this IPT computes at the traces' speed, one with twice as much twice as fast.
REFERENCE_SERVER_IPT = 1e9
#: YAFS's link ``BW`` is megabytes per time unit (its delay is bytes / (BW · 1e6) + PR); the
#: edge model works in bits per second, so one unit of BW is 8e6 bit/s. Converted here, at
#: the boundary, and nowhere else.
YAFS_BW_BPS = 8e6


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


def _is_number(value: Any) -> TypeGuard[int | float]:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _is_node_id(value: Any) -> TypeGuard[int | str]:
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
        user_location: (x, y) of the user in metres (projected when the file gives degrees);
            zeros when absent.
        user_link_bandwidth_bps: the user–access point link's bandwidth (its YAFS ``BW``, in
            megabytes per second, converted to bits per second).
        user_link_pr_s: PR of the user–access point link (s).
        server_link_bandwidth_bps: each access point–server link's bandwidth, per edge server
            node (bits per second, from ``BW``).
        server_link_pr_s: PR of each access point–server link, per edge server node (s).
        server_ipt: each edge server's YAFS ``IPT`` (``REFERENCE_SERVER_IPT`` when absent).
        server_capacity: each edge server's ``capacity`` (None when absent).
        server_positions_m: each edge server's (x, y) in metres, per edge server node; empty
            when the file places no server.
        origin: the point the file's degrees are projected around (the first entity with
            degrees); None when the file gives metres or no position.
    """

    source: str
    data: dict[str, Any]
    user_node: int | str
    access_point_node: int | str
    edge_server_nodes: tuple[int | str, ...]
    conditions: dict[int | str, int]
    load_devices: dict[int | str, int | None]
    user_location: tuple[float, float]
    user_link_bandwidth_bps: float
    user_link_pr_s: float
    server_link_bandwidth_bps: dict[int | str, float]
    server_link_pr_s: dict[int | str, float]
    server_ipt: dict[int | str, float] = field(default_factory=dict)
    server_capacity: dict[int | str, int | None] = field(default_factory=dict)
    server_positions_m: dict[int | str, tuple[float, float]] = field(default_factory=dict)
    origin: Origin | None = None


@dataclass
class _Nodes:
    """What a topology's entities say, before its links are read."""

    types: dict[int | str, str] = field(default_factory=dict)
    user_location: tuple[float, float] = (0.0, 0.0)
    server_order: list[int | str] = field(default_factory=list)
    load_devices: dict[int | str, int | None] = field(default_factory=dict)
    server_ipt: dict[int | str, float] = field(default_factory=dict)
    server_capacity: dict[int | str, int | None] = field(default_factory=dict)

    def only(self, kind: str, name: str) -> int | str:
        """The one node of ``kind`` (a user, an access point), or ScenarioError."""
        nodes = [node for node, node_kind in self.types.items() if node_kind == kind]
        if len(nodes) != 1:
            raise ScenarioError(name, "entity.type", f"expected exactly one {kind!r}, found {len(nodes)}")
        return nodes[0]


@dataclass
class _Links:
    """What a topology's links say."""

    conditions: dict[int | str, int] = field(default_factory=dict)
    server_bps: dict[int | str, float] = field(default_factory=dict)
    server_pr_s: dict[int | str, float] = field(default_factory=dict)
    user_bps: float | None = None
    user_pr_s: float | None = None


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
    nodes = _read_entities(name, entities)
    user, access_point = nodes.only(USER_TYPE, name), nodes.only(ACCESS_POINT_TYPE, name)
    if not nodes.server_order:
        raise ScenarioError(name, "entity.type", "no 'edge_server' entity")
    read = _read_links(name, links, nodes, user, access_point)
    assert read.user_bps is not None and read.user_pr_s is not None  # _read_links checked both
    origin, positions = _read_positions(name, entities)
    nodes.user_location = positions.get(user, nodes.user_location)
    server_positions = {node: positions[node] for node in nodes.server_order if node in positions}
    return EdgeTopology(
        source=name,
        data=data,
        user_node=user,
        access_point_node=access_point,
        edge_server_nodes=tuple(nodes.server_order),
        conditions=read.conditions,
        load_devices=nodes.load_devices,
        user_location=nodes.user_location,
        user_link_bandwidth_bps=read.user_bps,
        user_link_pr_s=read.user_pr_s,
        server_link_bandwidth_bps=read.server_bps,
        server_link_pr_s=read.server_pr_s,
        server_ipt=nodes.server_ipt,
        server_capacity=nodes.server_capacity,
        server_positions_m=server_positions,
        origin=origin,
    )


def _read_entities(name: str, entities: list[Any]) -> _Nodes:
    nodes = _Nodes()
    for index, entity in enumerate(entities):
        where = f"entity[{index}]"
        if not isinstance(entity, dict):
            raise ScenarioError(name, where, "expected an object")
        node = entity.get("id")
        if not _is_node_id(node):
            raise ScenarioError(name, f"{where}.id", "missing or not an integer/string node id")
        if node in nodes.types:
            raise ScenarioError(name, f"{where}.id", f"duplicate node id {node!r}")
        kind = entity.get("type")
        if kind not in (USER_TYPE, ACCESS_POINT_TYPE, EDGE_SERVER_TYPE):
            raise ScenarioError(
                name,
                f"{where}.type",
                f"got {kind!r}; expected one of {USER_TYPE!r}, {ACCESS_POINT_TYPE!r}, "
                f"{EDGE_SERVER_TYPE!r}",
            )
        nodes.types[node] = kind
        if kind == EDGE_SERVER_TYPE:
            _read_server(name, where, node, entity, nodes)
    return nodes


def _read_positions(name: str, entities: list[dict[str, Any]]
                    ) -> tuple[Origin | None, dict[int | str, tuple[float, float]]]:
    """The user's and the edge servers' positions in metres, and the origin of degrees.

    One unit in a whole file (metres or degrees), and every edge server placed or none: a
    scenario where some servers have no place has no distance to them.
    """
    first_of_unit: dict[str, str] = {}  # "metres" / "degrees" -> the first entity giving them
    read: dict[int | str, tuple[float, float]] = {}
    placed_servers: list[str] = []
    unplaced_servers: list[str] = []
    for index, entity in enumerate(entities):
        where, kind = f"entity[{index}]", entity["type"]
        if kind not in (USER_TYPE, EDGE_SERVER_TYPE):
            continue
        has_metres = any(key in entity for key in METRE_KEYS)
        has_degrees = any(key in entity for key in DEGREE_KEYS)
        if has_metres and has_degrees:
            raise ScenarioError(name, where, "mixes metres (x, y) and degrees (lat, lon); give one of the two")
        if not (has_metres or has_degrees):
            if kind == EDGE_SERVER_TYPE:
                unplaced_servers.append(where)
            continue
        unit, other, keys = ("metres", "degrees", METRE_KEYS) if has_metres else ("degrees", "metres", DEGREE_KEYS)
        first_of_unit.setdefault(unit, where)
        if other in first_of_unit:
            raise ScenarioError(name, where, f"gives {unit} but {first_of_unit[other]} gives {other}; "
                                "one unit for the whole file")
        # The user's x or y alone defaults the other to 0, as before positions existed.
        default = 0.0 if kind == USER_TYPE and unit == "metres" else None
        values = []
        for key in keys:
            value = entity.get(key, default)
            if value is None:
                raise ScenarioError(name, f"{where}.{key}", f"missing; {' and '.join(keys)} go together")
            if not _is_number(value):
                raise ScenarioError(name, f"{where}.{key}", f"not a finite number: {value!r}")
            values.append(float(value))
        if unit == "degrees":
            try:
                check_degrees(values[0], values[1])
            except PositionError as error:
                raise ScenarioError(name, where, str(error)) from None
        read[entity["id"]] = (values[0], values[1])
        if kind == EDGE_SERVER_TYPE:
            placed_servers.append(where)
    if placed_servers and unplaced_servers:
        raise ScenarioError(name, unplaced_servers[0], "has no position while other edge servers have "
                            "one; place every edge server or none")
    if "degrees" not in first_of_unit:
        return None, read
    origin = Origin(*next(iter(read.values())))
    return origin, {node: project_m(lat, lon, origin) for node, (lat, lon) in read.items()}


def _read_server(name: str, where: str, node: int | str, entity: dict[str, Any], nodes: _Nodes) -> None:
    device = entity.get(LOAD_DEVICE_KEY)
    if device is not None and (not isinstance(device, int) or isinstance(device, bool) or device < 0):
        raise ScenarioError(name, f"{where}.{LOAD_DEVICE_KEY}", f"not a non-negative integer: {device!r}")
    nodes.load_devices[node] = device
    ipt = entity.get(IPT_KEY, REFERENCE_SERVER_IPT)
    if not _is_number(ipt) or ipt <= 0:
        raise ScenarioError(name, f"{where}.{IPT_KEY}", f"not a positive number: {ipt!r}")
    nodes.server_ipt[node] = float(ipt)
    capacity = entity.get(CAPACITY_KEY)
    if capacity is not None and (not isinstance(capacity, int) or isinstance(capacity, bool) or capacity < 1):
        raise ScenarioError(name, f"{where}.{CAPACITY_KEY}", f"not a positive integer: {capacity!r}")
    nodes.server_capacity[node] = capacity
    nodes.server_order.append(node)


def _read_links(name: str, links: list[Any], nodes: _Nodes, user: int | str,
                access_point: int | str) -> _Links:
    read = _Links()
    for index, link in enumerate(links):
        where = f"link[{index}]"
        if not isinstance(link, dict):
            raise ScenarioError(name, where, "expected an object")
        ends: list[int | str] = []
        for key in ("s", "d"):
            node = link.get(key)
            if not _is_node_id(node) or node not in nodes.types:
                raise ScenarioError(name, f"{where}.{key}", f"unknown node id {node!r}")
            ends.append(node)
        for key in ("BW", "PR"):
            value = link.get(key)
            if not _is_number(value) or value < 0 or (key == "BW" and value == 0):
                raise ScenarioError(name, f"{where}.{key}", f"missing or not a positive number: {value!r}")
        pair = set(ends)
        if pair == {user, access_point}:
            read.user_bps, read.user_pr_s = float(link["BW"]) * YAFS_BW_BPS, float(link["PR"])
            continue
        servers = [node for node in ends if nodes.types[node] == EDGE_SERVER_TYPE]
        if len(servers) != 1 or access_point not in pair:
            raise ScenarioError(name, where, "only user-access_point and access_point-edge_server links are supported")
        server = servers[0]
        if server in read.conditions:
            raise ScenarioError(name, where, f"edge server {server!r} has a second link")
        condition = link.get(CONDITION_KEY)
        if not isinstance(condition, int) or isinstance(condition, bool):
            raise ScenarioError(name, f"{where}.{CONDITION_KEY}", f"missing or not an integer: {condition!r}")
        read.conditions[server] = condition
        read.server_bps[server] = float(link["BW"]) * YAFS_BW_BPS
        read.server_pr_s[server] = float(link["PR"])
    if read.user_bps is None or read.user_pr_s is None:
        raise ScenarioError(name, "link", "no link between the user and the access point")
    for server in nodes.server_order:
        if server not in read.conditions:
            raise ScenarioError(name, "link", f"edge server {server!r} is not linked to the access point")
    return read
