"""Routing policies shipped with YAFS3 (``yafs.path_routing``)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import networkx as nx

from yafs_safetail.yafs.selection import Selection

#: Key of this module's shortest paths in a graph's ``__networkx_cache__``.
_PATHS_KEY = "yafs_safetail.path_routing.shortest_paths"


class DeviceSpeedAwareRouting(Selection):
    """YAFS3's routing: the replica closest in hops; ties go to a replica never used yet.

    Reproduces YAFS3's choice exactly: among the replicas at the minimum hop count, the
    first one (in deployment order) that has never been selected, else the first one; the
    path returned is the one to the *first* replica found at that distance. No path (or an
    unknown node) gives ``([], None)`` with a warning, as in YAFS3. ``cache`` and
    ``invalid_cache_value`` are kept for scripts that set them (YAFS3 does not use them).
    """

    def __init__(self) -> None:
        super().__init__()
        self.cache: dict[Any, Any] = {}
        self.counter: Counter[Any] = Counter()
        self.invalid_cache_value = True
        self.controlServices: dict[tuple[Any, Any], tuple[list[Any], Any]] = {}

    def compute_BEST_DES(self, node_src, alloc_DES, sim, DES_dst, message):  # noqa: N802, N803
        """Return ``(path, des)`` of the chosen replica, or ``([], None)`` if a replica's
        node is unreachable (YAFS3 gives up on the first such replica)."""
        best_len = float("inf")
        best_path: list[Any] = []
        best_des: Any = []
        tied: list[Any] = []
        graph = sim.topology.G
        # Shortest paths are kept in networkx's own per-graph cache, which networkx empties
        # whenever the graph changes (nodes, edges or attributes): same paths, computed once.
        cache = getattr(graph, "__networkx_cache__", None)
        known = cache.setdefault(_PATHS_KEY, {}) if cache is not None else {}
        for des in DES_dst:
            node_dst = alloc_DES[des]
            path = known.get((node_src, node_dst))
            if path is None:
                try:
                    path = list(nx.shortest_path(graph, source=node_src, target=node_dst))
                except (nx.NetworkXNoPath, nx.NodeNotFound):
                    self.logger.warning("There is no path between two nodes: %s - %s", node_src, node_dst)
                    return [], None
                if cache is not None:
                    known[(node_src, node_dst)] = path
            path = list(path)
            if len(path) < best_len:
                best_len, best_path, best_des, tied = len(path), path, des, []
            elif len(path) == best_len:
                if not tied:
                    tied.append(best_des)
                tied.append(des)
        if tied:
            for des in tied:
                if des not in self.counter:
                    return best_path, des
            return best_path, tied[0]
        return best_path, best_des

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        service = message.dst
        path, des = self.compute_BEST_DES(topology_src, alloc_DES, sim, alloc_module[app_name][service], message)
        try:
            self.counter[int(des)] += 1
        except TypeError:  # no replica (des is [] or None): nothing to send
            return [], None
        self.controlServices[(topology_src, service)] = (path, des)
        return [path], [des]

    def clear_routing_cache(self) -> None:
        """Forget replica usage (YAFS API)."""
        self.invalid_cache_value = False
        self.cache = {}
        self.counter = Counter()
        self.controlServices = {}

    def get_path_from_failure(self, sim, message, link, alloc_DES, alloc_module, traffic, ctime, from_des):
        """YAFS3's re-routing: a new path from the failed link's first node, joined to the part
        of the old path before it; the message resumes from that node (``dst_int``)."""
        idx = message.path.index(link[0])
        if idx == len(message.path):
            return [], []
        node_src = message.path[idx]
        path, des = self.get_path(sim, message.app_name, message, node_src, alloc_DES, alloc_module, traffic, from_des)
        if len(path[0]) > 0:
            joined = message.path[0:message.path.index(path[0][0])] + path[0]
            message.dst_int = node_src
            return [joined], des
        return [], []
