"""What the YAFS3-style scenarios share: the library under test and small graph/app builders."""

from __future__ import annotations

import importlib
from types import SimpleNamespace
from typing import Any

import networkx as nx

MODULES = ("core", "topology", "application", "placement", "population", "selection",
           "distribution", "path_routing")


def library(package: str) -> SimpleNamespace:
    """The YAFS modules of ``package`` (``"yafs"`` or ``"yafs_safetail.yafs"``)."""
    return SimpleNamespace(**{name: importlib.import_module(f"{package}.{name}") for name in MODULES})


def _unit_graph(graph: nx.Graph, pr: float = 1, bw: float = 1, ipt: float = 100) -> nx.Graph:
    nx.set_edge_attributes(graph, name="PR", values=dict.fromkeys(graph.edges(), pr))
    nx.set_edge_attributes(graph, name="BW", values=dict.fromkeys(graph.edges(), bw))
    nx.set_node_attributes(graph, name="IPT", values=dict.fromkeys(graph.nodes(), ipt))
    return graph


def _one_module_apps(count: int, instructions: int = 30, size: int = 20) -> list[dict[str, Any]]:
    return [{"name": i, "module": [{"name": f"{i}_01", "RAM": 1}],
             "message": [{"name": f"M.USER.APP.{i}", "s": "None", "d": f"{i}_01",
                          "bytes": size, "instructions": instructions}],
             "transmission": [{"message_in": f"M.USER.APP.{i}", "module": f"{i}_01"}]}
            for i in range(count)]


# ----------------------------------------------------------------------------- tutorial 01
