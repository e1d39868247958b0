"""The network: a networkx graph whose edges carry BW/PR and whose nodes carry IPT."""

from __future__ import annotations

import os
from typing import Any

import networkx as nx

from yafs_safetail.yafs.errors import (
    YAFSInputError,
    read_json_input,
    require_id,
    require_list,
    require_mapping,
    require_number,
)


class Topology:
    """A YAFS topology.

    Attributes:
        G: the undirected ``networkx.Graph``; edges carry ``BW`` and ``PR``, nodes ``IPT``
            (plus any other entity keys).
        nodeAttributes: node id -> the entity dict it was loaded from (YAFS name).
    """

    LINK_BW = "BW"
    LINK_PR = "PR"
    NODE_IPT = "IPT"

    def __init__(self) -> None:
        self.G: nx.Graph = nx.Graph()
        self.nodeAttributes: dict[Any, dict[str, Any]] = {}
        self.source: str = "topology (in-memory)"

    def load(self, data: dict[str, Any] | str | os.PathLike[str]) -> None:
        """Build the graph from a YAFS topology JSON (a dict, or a path to the file).

        Links become undirected edges with all their keys except ``s``/``d`` as attributes;
        entities give node attributes. As in YAFS, an entity that appears in no link is
        not a graph node (it stays in ``nodeAttributes``).

        Raises:
            YAFSInputError: not JSON, missing/mistyped keys, negative or zero BW, negative
                PR or IPT, duplicate entity ids, or a link naming a node with no entity.
        """
        data, source = read_json_input(data, "topology")
        root = require_mapping(data, source, "")
        entities = require_list(root, "entity", source, "")
        links = require_list(root, "link", source, "")

        attributes: dict[Any, dict[str, Any]] = {}
        for index, raw in enumerate(entities):
            entry = f"entity[{index}]"
            entity = require_mapping(raw, source, entry)
            node_id = require_id(entity, "id", source, entry)
            require_number(entity, self.NODE_IPT, source, entry, positive=True, required=False)
            if node_id in attributes:
                raise YAFSInputError(source, entry, "id", f"duplicate entity id {node_id!r}")
            attributes[node_id] = dict(entity)

        graph = nx.Graph()
        for index, raw in enumerate(links):
            entry = f"link[{index}]"
            link = require_mapping(raw, source, entry)
            ends = [require_id(link, key, source, entry) for key in ("s", "d")]
            require_number(link, self.LINK_BW, source, entry, positive=True)
            require_number(link, self.LINK_PR, source, entry)
            for key, node_id in zip(("s", "d"), ends, strict=True):
                if attributes and node_id not in attributes:
                    raise YAFSInputError(
                        source, entry, key, f"names node {node_id!r}, which is not an entity"
                    )
            edge_attrs = {k: v for k, v in link.items() if k not in ("s", "d")}
            graph.add_edge(ends[0], ends[1], **edge_attrs)

        for node_id, entity in attributes.items():
            if node_id in graph:
                graph.nodes[node_id].update(entity)

        self.G = graph
        self.nodeAttributes = attributes
        self.source = source

    def get_edges(self) -> dict[tuple[Any, Any], dict[str, Any]]:
        """Return ``{(u, v): edge attributes}`` for every (undirected) edge."""
        return {(u, v): data for u, v, data in self.G.edges(data=True)}

    def get_edge(self, key: tuple[Any, Any]) -> dict[str, Any]:
        """Return the attributes of edge ``key`` (either direction)."""
        return self.G.edges[key]

    def get_nodes(self) -> list[Any]:
        """Return the graph's node ids."""
        return list(self.G.nodes)

    def get_nodes_att(self) -> dict[Any, dict[str, Any]]:
        """Return ``{node id: attributes}`` of the graph's nodes."""
        return {node: data for node, data in self.G.nodes(data=True)}

    def get_info(self) -> dict[Any, dict[str, Any]]:
        """Alias of :meth:`get_nodes_att` kept for YAFS scripts."""
        return self.get_nodes_att()

    def find_IDs(self, value: dict[str, Any]) -> list[Any]:  # noqa: N802 - YAFS name
        """Return the ids of nodes whose attribute equals the one given (one key only)."""
        key, wanted = next(iter(value.items()))
        candidates = self.nodeAttributes or {n: d for n, d in self.G.nodes(data=True)}
        return [node for node, attrs in candidates.items() if key in attrs and attrs[key] == wanted]

    def size(self) -> int:
        """Return the number of graph nodes."""
        return self.G.number_of_nodes()

    def add_node(self, node_id: Any, **attrs: Any) -> None:
        """Add a node with attributes."""
        self.G.add_node(node_id, **attrs)

    def add_edge(self, src: Any, dst: Any, **attrs: Any) -> None:
        """Add an undirected edge with attributes (``BW``, ``PR``...)."""
        self.G.add_edge(src, dst, **attrs)

    def remove_node(self, node_id: Any) -> int:
        """Remove a node and its edges; return the new size."""
        self.G.remove_node(node_id)
        return self.size()
