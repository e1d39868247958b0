"""The network: a networkx graph whose edges carry BW/PR and whose nodes carry IPT."""

from __future__ import annotations

import logging
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
        nodeAttributes: node id -> the entity it was loaded from, with YAFS's ``uptime``
            ``(0, None)`` added (YAFS name; empty when the graph was assigned directly).
    """

    LINK_BW = "BW"
    LINK_PR = "PR"
    NODE_IPT = "IPT"

    def __init__(self, logger: logging.Logger | None = None) -> None:
        self.G: nx.Graph = nx.Graph()
        self.nodeAttributes: dict[Any, dict[str, Any]] = {}
        self.source: str = "topology (in-memory)"
        self.logger = logger or logging.getLogger(__name__)

    def load(self, data: dict[str, Any] | str | os.PathLike[str]) -> None:
        """Build the graph from a YAFS topology JSON (a dict, or a path to the file).

        Links become undirected edges with all their keys except ``s``/``d`` as attributes;
        entities give node attributes, and a node whose entity has no ``IPT`` gets
        ``IPT = 0`` (YAFS). As in YAFS, an entity that appears in no link is not a graph node
        (it stays in ``nodeAttributes``).

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
            attributes[node_id] = {**entity, "uptime": (0, None)}

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
                graph.nodes[node_id].update({k: v for k, v in entity.items() if k != "uptime"})
                graph.nodes[node_id].setdefault(self.NODE_IPT, 0)

        self.G = graph
        self.nodeAttributes = attributes
        self.source = source

    def load_all_node_attr(self, data: dict[str, Any] | str | os.PathLike[str]) -> None:
        """YAFS3's second loader: the same graph as :meth:`load` (every entity key becomes
        a node attribute here too)."""
        self.load(data)

    def create_topology_from_graph(self, G: nx.Graph) -> None:  # noqa: N803 - YAFS name
        """Use an existing networkx graph (edges need ``BW``/``PR``, nodes ``IPT``).

        Raises:
            TypeError: ``G`` is not a networkx graph (YAFS).
        """
        if not isinstance(G, nx.Graph):
            raise TypeError(f"create_topology_from_graph: expected a networkx Graph, got {type(G).__name__}")
        self.G = G

    def create_random_topology(self, nxGraphGenerator: Any, params: Any) -> None:  # noqa: N803
        """``G = nxGraphGenerator(*params)`` (YAFS); attributes are still to be set."""
        self.G = nxGraphGenerator(*params)

    def load_graphml(self, filename: str | os.PathLike[str]) -> None:
        """Read a GraphML file; every edge gets ``BW = PR = 1`` and every node ``IPT = 1``
        (YAFS3), and ``nodeAttributes`` lists the nodes' attributes. Node ids stay strings,
        as networkx reads them."""
        graph = nx.read_graphml(filename)
        nx.set_edge_attributes(graph, {edge: {self.LINK_BW: 1, self.LINK_PR: 1} for edge in graph.edges()})
        nx.set_node_attributes(graph, {node: {self.NODE_IPT: 1} for node in graph.nodes()})
        self.G = graph
        self.nodeAttributes = {node: graph.nodes[node] for node in graph.nodes()}

    def get_edges(self) -> Any:
        """The graph's edge view (YAFS: ``G.edges``; iterate it for ``(u, v)`` pairs)."""
        return self.G.edges

    def get_edge(self, key: tuple[Any, Any]) -> dict[str, Any]:
        """Return the attributes of edge ``key`` (either direction)."""
        return self.G.edges[key]

    def get_nodes(self) -> Any:
        """The graph's node view (YAFS: ``G.nodes``)."""
        return self.G.nodes

    def get_node(self, key: Any) -> dict[str, Any]:
        """The attributes of node ``key``."""
        return self.G.nodes[key]

    def get_nodes_att(self) -> dict[Any, dict[str, Any]]:
        """YAFS's ``nodeAttributes``: the loaded entities (empty for an assigned graph)."""
        return self.nodeAttributes

    def get_info(self) -> dict[Any, dict[str, Any]]:
        """Alias of :meth:`get_nodes_att` (YAFS)."""
        return self.nodeAttributes

    def find_IDs(self, value: dict[str, Any], graph: bool = False) -> list[Any]:  # noqa: N802 - YAFS name
        """Ids of the entities whose attribute equals the one given (one key only).

        As YAFS3 this searches ``nodeAttributes`` (the loaded entities, in file order), so a
        topology given as a bare graph finds nothing; ``graph=True`` searches the graph's
        node attributes instead.
        """
        key, wanted = next(iter(value.items()))
        candidates = dict(self.G.nodes(data=True)) if graph else self.nodeAttributes
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
