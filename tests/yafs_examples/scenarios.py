"""Builders of small YAFS scenarios for the core tests (written for these tests)."""

from __future__ import annotations

from typing import Any

import networkx as nx

from yafs_safetail.yafs.application import Application, Message
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.placement import Placement
from yafs_safetail.yafs.population import Population
from yafs_safetail.yafs.selection import Selection
from yafs_safetail.yafs.topology import Topology


class MulticastAll(Selection):
    """Send every message to every replica of its destination module (shortest paths)."""

    def __init__(self) -> None:
        super().__init__()
        self.completed: list[Any] = []

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        replicas = alloc_module[app_name][message.dst]
        paths = [nx.shortest_path(sim.topology.G, topology_src, alloc_DES[d]) for d in replicas]
        return paths, list(replicas)

    def on_request_complete(self, sim, outcome):
        self.completed.append(outcome)


class ReplyToSender(Selection):
    """Requests go to every replica; replies go back to the user sink on the request's source node."""

    def __init__(self) -> None:
        super().__init__()
        self.completed: list[Any] = []

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        replicas = alloc_module[app_name][message.dst]
        if message.original_DES_src is not None and message.dst in sim.apps[app_name].get_sink_modules():
            user_node = sim.alloc_DES[message.original_DES_src]
            sinks = [d for d in replicas if alloc_DES[d] == user_node]
            return [nx.shortest_path(sim.topology.G, topology_src, user_node)], sinks[:1]
        paths = [nx.shortest_path(sim.topology.G, topology_src, alloc_DES[d]) for d in replicas]
        return paths, list(replicas)

    def on_request_complete(self, sim, outcome):
        self.completed.append(outcome)


class FixedPlacement(Placement):
    """Deploy ``module`` once on each node of ``nodes``."""

    def __init__(self, module: str, nodes: list[Any]) -> None:
        super().__init__("fixed")
        self.module = module
        self.nodes = nodes

    def initial_allocation(self, sim, app_name):
        services = sim.apps[app_name].services[self.module]
        for node in self.nodes:
            sim.deploy_module(app_name, self.module, services, [node])


class UserPopulation(Population):
    """One user on ``node`` emitting ``message`` every ``period``; optional sink there too."""

    def __init__(self, node: Any, message: str, period: float, sink: str | None = None) -> None:
        super().__init__("users")
        self.node = node
        self.message = message
        self.period = period
        self.sink = sink

    def initial_allocation(self, sim, app_name):
        app = sim.apps[app_name]
        sim.deploy_source(app_name, id_node=self.node, msg=app.get_message(self.message),
                          distribution=deterministic_distribution(self.period))
        if self.sink is not None:
            sim.deploy_sink(app_name, node=self.node, module=self.sink)


def line_topology(links: list[tuple[Any, Any, float, float]], ipt: dict[Any, float]) -> Topology:
    """A topology from ``(s, d, BW, PR)`` links and per-node IPT."""
    topology = Topology()
    topology.load({
        "entity": [{"id": node, "IPT": value} for node, value in ipt.items()],
        "link": [{"s": s, "d": d, "BW": bw, "PR": pr} for s, d, bw, pr in links],
    })
    return topology


def consume_app(size_bytes: int, instructions: float = 0) -> Application:
    """User message ``Req`` consumed by module ``Svc`` (no reply)."""
    app = Application("consume")
    app.set_modules([{"Svc": {"RAM": 1, "Type": Application.TYPE_MODULE}}])
    req = Message("Req", "None", "Svc", instructions=instructions, bytes=size_bytes)
    app.add_source_messages(req)
    app.add_service_module("Svc", req)
    return app


def request_reply_app(request_bytes: int, reply_bytes: int, instructions: float) -> Application:
    """User ``Req`` -> module ``Svc`` -> ``Resp`` -> sink ``Client`` (a request/reply service)."""
    app = Application("rr")
    app.set_modules([
        {"User": {"Type": Application.TYPE_SOURCE}},
        {"Svc": {"RAM": 1, "Type": Application.TYPE_MODULE}},
        {"Client": {"Type": Application.TYPE_SINK}},
    ])
    req = Message("Req", "User", "Svc", instructions=instructions, bytes=request_bytes)
    resp = Message("Resp", "Svc", "Client", instructions=0, bytes=reply_bytes)
    app.add_source_messages(req)
    app.add_service_module("Svc", req, resp)
    return app


def edge_sim(tmp_path, *, service_model=None, ipt_servers=(1000.0, 2000.0, 4000.0), **sim_kwargs) -> tuple[Sim, ReplyToSender]:
    """User 0 - access point 1 - servers 2.. ; request/reply multicast to every server."""
    servers = list(range(2, 2 + len(ipt_servers)))
    links = [(0, 1, 1.0, 0.5)] + [(1, s, 1.0, 1.0) for s in servers]
    ipt = {0: 1.0, 1: 1.0, **dict(zip(servers, ipt_servers, strict=True))}
    sim = Sim(line_topology(links, ipt), default_results_path=str(tmp_path / "edge"),
              service_model=service_model, **sim_kwargs)
    selection = ReplyToSender()
    sim.deploy_app(request_reply_app(1000, 2000, 1000.0), FixedPlacement("Svc", servers),
                   UserPopulation(0, "Req", 100, sink="Client"), selection)
    return sim, selection
