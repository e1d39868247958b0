"""Routing policies shipped with YAFS3 (``yafs.path_routing``)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import networkx as nx

from yafs_safetail.yafs.selection import Selection


class DeviceSpeedAwareRouting(Selection):
    """The replica closest in hops (a shortest path); ties go to a replica never used yet.

    This reproduces YAFS3's choice: among replicas at the minimum hop count, the first one
    (in deployment order) that has never been selected, else the first one. The path is the
    one to the first replica found at the minimum distance.
    """

    def __init__(self) -> None:
        super().__init__()
        self.counter: Counter[Any] = Counter()
        self.controlServices: dict[tuple[Any, Any], tuple[list[Any], Any]] = {}

    def compute_BEST_DES(self, node_src, alloc_DES, sim, DES_dst, message):  # noqa: N802, N803
        """Return ``(path, des)`` of the chosen replica, or ``([], None)`` if none is reachable."""
        best_len = float("inf")
        best_path: list[Any] = []
        best_des = None
        tied: list[Any] = []
        for des in DES_dst:
            try:
                path = nx.shortest_path(sim.topology.G, source=node_src, target=alloc_DES[des])
            except (nx.NetworkXNoPath, nx.NodeNotFound):
                continue
            if len(path) < best_len:
                best_len, best_path, best_des, tied = len(path), list(path), des, []
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
        replicas = alloc_module[app_name].get(message.dst, [])
        path, des = self.compute_BEST_DES(topology_src, alloc_DES, sim, replicas, message)
        if des is None:
            return [], []
        self.counter[des] += 1
        self.controlServices[(topology_src, message.dst)] = (path, des)
        return [path], [des]

    def clear_routing_cache(self) -> None:
        """Forget replica usage (YAFS API)."""
        self.counter = Counter()
        self.controlServices = {}

    def get_path_from_failure(self, sim, message, link, alloc_DES, alloc_module, traffic, ctime, from_des):
        node_src = link[0]
        path, des = self.get_path(sim, message.app_name, message, node_src, alloc_DES, alloc_module, traffic, from_des)
        if not path or not path[0]:
            return [], []
        return path, des
