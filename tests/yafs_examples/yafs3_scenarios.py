"""Small scenarios in the spirit of YAFS3's tutorials and examples, for golden tests.

Each scenario is written against the YAFS3 API only, and takes the library as a parameter
(:func:`library`: ``"yafs"`` for YAFS3 itself, ``"yafs_safetail.yafs"`` for this core), so
the very same code produced the golden CSVs on real YAFS3 (outside this repository, see
docs/core.md) and runs in the tests on our core. Each one writes ``<results>.csv`` and
``<results>_link.csv`` with at most a few hundred rows. Like YAFS3's scripts, they draw from
the global ``random`` and ``numpy.random`` generators: :func:`run` seeds both first.

The scenarios and what each exercises:

* ``basic`` (tutorial 01): a graph assigned to ``Topology.G``, JSON applications and
  placement, ``DeviceSpeedAwareRouting`` with two equally distant replicas, a user on a
  replica's own node, a two-module chain.
* ``service_movement`` (tutorial 02): a monitor moving replicas at random while messages
  are in flight to them (a stopped replica serves one more message; one whose node entry
  is gone writes no row).
* ``topology_changes`` (tutorial 03): nodes removed under messages in flight (YAFS's
  re-routing from ``get_path_from_failure`` and ``dst_int``), ``remove_node`` forgetting
  only the first process of a node, nodes and links added during the run.
* ``user_movement`` (tutorial 04): users created, moved and removed by a monitor (process
  ids taken during the run come after YAFS's stop monitor's).
* ``tutorial_main`` (examples/Tutorial main2/main3): a JSON topology, ``Statical`` sinks and
  sources by device model, replicas scaled on the cloud, round robin then broadcast to two
  sinks, a population whose control process stops itself.
* ``vrgame`` (examples/VRGameFog): module source services (messages with id -1), several
  transmissions per module, a forwarding filter with threshold 0.5 (global draws), routing
  by ``last_idDes``, broadcast to every client, the string ``get_sink_modules``.
* ``failures`` (examples/DynamicFailuresOnNodes): ``NoPlacementOfModules``,
  ``exponentialDistributionStartPoint`` (numpy's global draws), a population removing nodes,
  a selection whose re-routing moves ``dst_int`` two nodes ahead.
* ``json_modelling`` (examples/Tutorial_JSONModelling, TestJsons): ``Topology.load``,
  ``create_applications_from_json``, ``JSONPlacementOnCloud``, ``exponentialDistribution``
  and ``uniformDistribution`` users, a zero-instruction module on an integer clock, copies
  queueing on a shared link (``buffer``).
"""

from __future__ import annotations

import importlib
import random
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import networkx as nx
import numpy as np

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


def basic(lib: SimpleNamespace, results: str) -> None:
    topology = lib.topology.Topology()
    topology.G = _unit_graph(nx.generators.binomial_tree(4))
    apps_json = _one_module_apps(3)
    apps_json.append({
        "name": 3, "module": [{"name": "3_A", "RAM": 1}, {"name": "3_B", "RAM": 1}],
        "message": [{"name": "M.USER.APP.3", "s": "None", "d": "3_A", "bytes": 500, "instructions": 50},
                    {"name": "M.3.AB", "s": "3_A", "d": "3_B", "bytes": 1000, "instructions": 20}],
        "transmission": [{"message_in": "M.USER.APP.3", "module": "3_A", "message_out": "M.3.AB"},
                         {"message_in": "M.3.AB", "module": "3_B"}]})
    apps = lib.application.create_applications_from_json(apps_json)
    allocation = {"initialAllocation": [
        {"module_name": "0_01", "app": 0, "id_resource": 0},
        {"module_name": "1_01", "app": 1, "id_resource": 0},
        {"module_name": "1_01", "app": 1, "id_resource": 3},
        {"module_name": "2_01", "app": 2, "id_resource": 1},
        {"module_name": "2_01", "app": 2, "id_resource": 2},  # two replicas, tie on hops
        {"module_name": "3_A", "app": 3, "id_resource": 8},
        {"module_name": "3_B", "app": 3, "id_resource": 0}]}
    placement = lib.placement.JSONPlacement(name="Placement", json=allocation)
    selector = lib.path_routing.DeviceSpeedAwareRouting()
    sim = lib.core.Sim(topology, default_results_path=results)
    for name in apps:
        sim.deploy_app(apps[name], placement, selector)
    users = [(0, 5), (1, 7), (1, 3), (2, 0), (2, 0), (3, 12), (0, 15)]
    for app_name, node in users:
        msg = sim.apps[app_name].get_message(f"M.USER.APP.{app_name}")
        sim.deploy_source(app_name, id_node=node, msg=msg,
                          distribution=lib.distribution.deterministic_distribution(100, name="Deterministic"))
    sim.run(700)


# ----------------------------------------------------------------------------- tutorial 02


def service_movement(lib: SimpleNamespace, results: str) -> None:
    topology = lib.topology.Topology()
    topology.G = _unit_graph(nx.generators.binomial_tree(4), pr=3)
    apps = lib.application.create_applications_from_json(_one_module_apps(3))
    allocation = {"initialAllocation": [{"module_name": f"{i}_01", "app": i, "id_resource": i} for i in range(3)]}
    placement = lib.placement.JSONPlacement(name="Placement", json=allocation)
    selector = lib.path_routing.DeviceSpeedAwareRouting()
    sim = lib.core.Sim(topology, default_results_path=results)
    for name in apps:
        sim.deploy_app(apps[name], placement, selector)
    for app_name, node in [(0, 9), (1, 14), (2, 6), (0, 11)]:
        sim.deploy_source(app_name, id_node=node, msg=sim.apps[app_name].get_message(f"M.USER.APP.{app_name}"),
                          distribution=lib.distribution.deterministic_distribution(50, name="D"))

    def move(sim: Any) -> None:
        entities = sim.get_alloc_entities()
        services = {}
        for node in sorted(entities):
            for entry in entities[node]:
                if "None" not in entry:
                    services.setdefault(entry[entry.index("#") + 1:], []).append(node)
        for service in sorted(services):
            app_name = int(service[:service.index("_")])
            for node in services[service]:
                new_node = random.choice(sorted(sim.topology.G.nodes()))
                if new_node == node:
                    continue
                des = sim.get_DES_from_Service_In_Node(node, app_name, service)
                sim.undeploy_module(app_name, service, des)
                sim.deploy_module(app_name, service, sim.apps[app_name].services[service], [new_node])

    sim.deploy_monitor("Mover", move,
                       lib.distribution.deterministicDistributionStartPoint(251, 150, name="Start"), sim=sim)
    sim.run(800)


# ----------------------------------------------------------------------------- tutorial 03


def topology_changes(lib: SimpleNamespace, results: str) -> None:
    graph = nx.cycle_graph(10)
    graph.add_edges_from([(0, 5), (2, 7)])
    topology = lib.topology.Topology()
    topology.G = _unit_graph(graph, pr=10)
    apps = lib.application.create_applications_from_json(_one_module_apps(2, size=1000))
    allocation = {"initialAllocation": [{"module_name": "0_01", "app": 0, "id_resource": 0},
                                        {"module_name": "1_01", "app": 1, "id_resource": 6}]}
    placement = lib.placement.JSONPlacement(name="Placement", json=allocation)
    selector = lib.path_routing.DeviceSpeedAwareRouting()
    sim = lib.core.Sim(topology, default_results_path=results)
    for name in apps:
        sim.deploy_app(apps[name], placement, selector)
    for app_name, node in [(0, 3), (1, 1), (0, 8), (1, 4), (0, 3)]:
        sim.deploy_source(app_name, id_node=node, msg=sim.apps[app_name].get_message(f"M.USER.APP.{app_name}"),
                          distribution=lib.distribution.deterministic_distribution(40, name="D"))
    # Removals are timed so that no message is then heading *into* the removed node
    # (YAFS3's DeviceSpeedAwareRouting cannot re-route from a node that is gone).
    steps = iter(["remove 1", "remove 3", "add", "remove 9", "add"])

    def change(sim: Any) -> None:
        step = next(steps, "")
        if step.startswith("remove"):
            # Mid-flight: messages sent at the last multiple of 40 are on their way now.
            sim.remove_node(int(step.split()[1]))
        elif step == "add":
            new_id = max(sim.topology.G.nodes()) + 1
            ends = random.sample(sorted(sim.topology.G.nodes()), 2)
            sim.topology.G.add_node(new_id, IPT=100)
            for end in ends:
                sim.topology.G.add_edge(end, new_id, BW=10, PR=10)

    sim.deploy_monitor("Changes", change,
                       lib.distribution.deterministicDistributionStartPoint(125, 90, name="Start"), sim=sim)
    sim.run(560)


# ----------------------------------------------------------------------------- tutorial 04


def user_movement(lib: SimpleNamespace, results: str) -> None:
    topology = lib.topology.Topology()
    topology.G = _unit_graph(nx.generators.binomial_tree(4))
    apps = lib.application.create_applications_from_json(_one_module_apps(3))
    allocation = {"initialAllocation": [{"module_name": f"{i}_01", "app": i, "id_resource": i * 4} for i in range(3)]}
    placement = lib.placement.JSONPlacement(name="Placement", json=allocation)
    selector = lib.path_routing.DeviceSpeedAwareRouting()
    sim = lib.core.Sim(topology, default_results_path=results)
    for name in apps:
        sim.deploy_app(apps[name], placement, selector)
    users: list[int] = []

    def evolve(sim: Any) -> None:
        if not users or random.random() < 0.5:
            app_name = random.choice([0, 1, 2])
            node = random.choice(sorted(sim.topology.G.nodes()))
            users.append(sim.deploy_source(app_name, id_node=node,
                                           msg=sim.apps[app_name].get_message(f"M.USER.APP.{app_name}"),
                                           distribution=lib.distribution.deterministic_distribution(30, name="D")))
        elif random.random() < 0.6:
            user = random.choice(users)
            sim.alloc_DES[user] = random.choice(sorted(sim.topology.G.nodes()))
        else:
            user = random.choice(users)
            sim.undeploy_source(user)
            users.remove(user)

    sim.deploy_monitor("Users", evolve,
                       lib.distribution.deterministicDistributionStartPoint(10, 60, name="Start"), sim=sim)
    sim.run(600)


# ----------------------------------------------------------------------------- examples/Tutorial


def tutorial_main(lib: SimpleNamespace, results: str) -> None:
    application = lib.application
    app = application.Application(name="SimpleCase")
    app.set_modules([{"Sensor": {"Type": application.Application.TYPE_SOURCE}},
                     {"ServiceA": {"RAM": 10, "Type": application.Application.TYPE_MODULE}},
                     {"Actuator": {"Type": application.Application.TYPE_SINK}}])
    m_a = application.Message("M.A", "Sensor", "ServiceA", instructions=20 * 10**6, bytes=1000)
    m_b = application.Message("M.B", "ServiceA", "Actuator", instructions=30 * 10**6, bytes=500,
                              broadcasting=True)
    app.add_source_messages(m_a)
    app.add_service_module("ServiceA", m_a, m_b, application.fractional_selectivity, threshold=1.0)
    topology = lib.topology.Topology()
    topology.load({
        "entity": [{"id": 0, "model": "cloud", "mytag": "cloud", "IPT": 5000 * 10**6},
                   {"id": 1, "model": "sensor-device", "IPT": 100 * 10**6},
                   {"id": 2, "model": "actuator-device", "IPT": 100 * 10**6},
                   {"id": 3, "model": "sensor-device", "IPT": 100 * 10**6}],
        "link": [{"s": 0, "d": 1, "BW": 1, "PR": 10}, {"s": 0, "d": 2, "BW": 1, "PR": 1},
                 {"s": 3, "d": 0, "BW": 2, "PR": 4}]})

    class OnCloud(lib.placement.Placement):
        def initial_allocation(self, sim, app_name):
            cloud = sim.topology.find_IDs({"mytag": "cloud"})
            services = sim.apps[app_name].services
            for module in services:
                for _ in range(self.scaleServices.get(module, 0)):
                    sim.deploy_module(app_name, module, services[module], cloud)

    class RoundRobinThenBroadcast(lib.selection.Selection):
        def __init__(self):
            super().__init__()
            self.turn = {}

        def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
            replicas = alloc_module[app_name][message.dst]
            if message.name == "M.A":
                index = self.turn.get(message.dst, 0)
                self.turn[message.dst] = (index + 1) % len(replicas)
                des = replicas[index]
                return [nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])], [des]
            return ([nx.shortest_path(sim.topology.G, topology_src, alloc_DES[d]) for d in replicas],
                    list(replicas))

    class StopAfter(lib.population.Statical):
        def __init__(self, runs, **kwargs):
            self.runs = runs
            super().__init__(**kwargs)

        def run(self, sim):
            if self.runs == 0:
                sim.stop_process(sim.get_DES(self.name))
            else:
                self.runs -= 1

    placement = OnCloud("onCloud")
    placement.scaleService({"ServiceA": 3})
    population = StopAfter(2, name="Statical",
                           activation_dist=lib.distribution.deterministic_distribution(150, name="A"))
    population.set_sink_control({"model": "actuator-device", "number": 2, "module": app.get_sink_modules()})
    population.set_src_control({"model": "sensor-device", "number": 1, "message": app.get_message("M.A"),
                                "distribution": lib.distribution.deterministic_distribution(100, name="D")})
    sim = lib.core.Sim(topology, default_results_path=results)
    sim.deploy_app2(app, placement, population, RoundRobinThenBroadcast())
    sim.run(1000)


# ----------------------------------------------------------------------------- examples/VRGameFog


def vrgame(lib: SimpleNamespace, results: str) -> None:
    application = lib.application
    app_cls, message = application.Application, application.Message
    app = app_cls(name="EGG_GAME")
    app.set_modules([{"EGG": {"Type": app_cls.TYPE_SOURCE}}, {"Display": {"Type": app_cls.TYPE_SINK}},
                     {"Client": {"RAM": 10, "Type": app_cls.TYPE_MODULE}},
                     {"Calculator": {"RAM": 10, "Type": app_cls.TYPE_MODULE}},
                     {"Coordinator": {"RAM": 10, "Type": app_cls.TYPE_MODULE}}])
    m_egg = message("M.EGG", "EGG", "Client", instructions=2000 * 10**6, bytes=500)
    m_sensor = message("M.Sensor", "Client", "Calculator", instructions=3500 * 10**6, bytes=500)
    m_state = message("M.Player_Game_State", "Calculator", "Coordinator", instructions=1000 * 10**6, bytes=1000)
    m_conc = message("M.Concentration", "Calculator", "Client", instructions=14 * 10**6, bytes=500)
    m_global = message("M.Global_Game_State", "Coordinator", "Client", instructions=28 * 10**6, bytes=1000,
                       broadcasting=True)
    m_update = message("M.Global_State_Update", "Client", "Display", instructions=1000 * 10**6, bytes=500)
    m_self = message("M.Self_State_Update", "Client", "Display", instructions=1000 * 10**6, bytes=500)
    app.add_source_messages(m_egg)
    every = lib.distribution.deterministic_distribution(100, name="D")
    app.add_service_source("Calculator", every, m_state)
    app.add_service_source("Coordinator", every, m_global)
    app.add_service_module("Client", m_egg, m_sensor, application.fractional_selectivity, threshold=0.5)
    app.add_service_module("Client", m_conc, m_self, application.fractional_selectivity, threshold=1.0)
    app.add_service_module("Client", m_global, m_update, application.fractional_selectivity, threshold=1.0)
    app.add_service_module("Calculator", m_sensor, m_conc, application.fractional_selectivity, threshold=1.0)
    app.add_service_module("Coordinator", m_state)

    entities = [{"id": 0, "model": "Cluster", "IPT": 44800 * 10**6},
                {"id": 1, "model": "Proxy-server", "IPT": 2800 * 10**6}]
    links = [{"s": 0, "d": 1, "BW": 10000, "PR": 14}]
    node = 2
    for _ in range(2):
        gateway = node
        entities.append({"id": gateway, "model": "d-", "IPT": 2800 * 10**6})
        links.append({"s": 1, "d": gateway, "BW": 100, "PR": 10})
        node += 1
        for _ in range(2):
            entities += [{"id": node, "model": "m-", "IPT": 1000 * 10**6}, {"id": node + 1, "model": "s"},
                         {"id": node + 2, "model": "a"}]
            links += [{"s": gateway, "d": node, "BW": 100, "PR": 2}, {"s": node, "d": node + 1, "BW": 100, "PR": 4},
                      {"s": node, "d": node + 2, "BW": 100, "PR": 1}]
            node += 3
    topology = lib.topology.Topology()
    topology.load({"entity": entities, "link": links})

    class OnCluster(lib.placement.Placement):
        def initial_allocation(self, sim, app_name):
            cluster = sim.topology.find_IDs({"model": "Cluster"})
            mobiles = sim.topology.find_IDs({"model": "m-"})
            services = sim.apps[app_name].services
            for module in services:
                if module in ("Coordinator", "Calculator"):
                    for _ in range(self.scaleServices[module]):
                        sim.deploy_module(app_name, module, services[module], cluster)
                elif module == "Client":
                    sim.deploy_module(app_name, module, services[module], mobiles)

    class CloudRoundRobin(lib.selection.Selection):
        def __init__(self):
            self.turn = {}

        def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
            replicas = alloc_module[app_name][message.dst]
            if message.name in ("M.Sensor", "M.Player_Game_State"):
                index = self.turn.get(message.dst, 0)
                self.turn[message.dst] = (index + 1) % len(replicas)
                des = replicas[index]
                return [nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])], [des]
            if message.name == "M.Concentration":
                replicas = [message.last_idDes[0]]
            best_path, best_des, shortest = [], [], float("inf")
            for des in replicas:
                path = nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])
                if message.broadcasting:
                    best_path.append(path)
                    best_des.append(des)
                elif len(path) <= shortest:
                    shortest, best_path, best_des = len(path), [path], [des]
            return best_path, best_des

    placement = OnCluster("onCloud")
    placement.scaleService({"Calculator": 2, "Coordinator": 1})
    population = lib.population.Statical("Statical")
    population.set_sink_control({"model": "a", "number": 1, "module": app.get_sink_modules()})
    population.set_src_control({"model": "s", "number": 1, "message": app.get_message("M.EGG"),
                                "distribution": lib.distribution.deterministic_distribution(100, name="D")})
    sim = lib.core.Sim(topology, default_results_path=results)
    sim.deploy_app2(app, placement, population, CloudRoundRobin())
    sim.run(450)


# ----------------------------------------------------------------------------- DynamicFailures


def failures(lib: SimpleNamespace, results: str) -> None:
    application = lib.application
    app = application.Application(name="app1")
    app.set_modules([{"Generator": {"Type": application.Application.TYPE_SOURCE}},
                     {"Actuator": {"Type": application.Application.TYPE_SINK}}])
    action = application.Message("M.Action", "Generator", "Actuator", instructions=100, bytes=10)
    app.add_source_messages(action)
    graph = nx.grid_2d_graph(4, 4)
    graph = nx.relabel_nodes(graph, {n: n[0] * 4 + n[1] for n in graph.nodes()})
    topology = lib.topology.Topology()
    topology.G = _unit_graph(graph, pr=3)

    class PopAndFailures(lib.population.Population):
        def __init__(self, sources, **kwargs):
            self.sources = sources
            self.removed = []
            super().__init__(**kwargs)

        def initial_allocation(self, sim, app_name):
            for ctrl in self.src_control:
                for node in self.sources:
                    sim.deploy_source(app_name, id_node=node, msg=ctrl["message"],
                                      distribution=ctrl["distribution"])
            for ctrl in self.sink_control:
                for node in ctrl["ids"]:
                    sim.deploy_sink(app_name, node=node, module=ctrl["module"])

        def run(self, sim):
            # Fail a node that carries traffic: an inner node of a route in use, hosting nothing.
            if len(self.removed) == 4:
                return
            routes = sim.selector_path[app.name].cache.values()
            inner = sorted({n for path, _ in routes for n in path[1:-1] if n in sim.topology.G}
                           - set(sim.alloc_DES.values()))
            if inner:
                node = random.choice(inner)
                self.removed.append(node)
                sim.remove_node(node)

    class Nearest(lib.selection.Selection):
        def __init__(self):
            self.cache = {}
            self.nodes = -1
            super().__init__()

        def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
            if self.nodes != len(sim.topology.G.nodes()):
                self.nodes = len(sim.topology.G.nodes())
                self.cache = {}
            if topology_src not in self.cache:
                best, best_des = [], None
                for des in alloc_module[app_name][message.dst]:
                    try:
                        path = nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])
                    except (nx.NetworkXNoPath, nx.NodeNotFound):
                        continue
                    if not best or len(path) < len(best):
                        best, best_des = path, des
                self.cache[topology_src] = (best, best_des)
            path, des = self.cache[topology_src]
            return [path], [des]

        def get_path_from_failure(self, sim, message, link, alloc_DES, alloc_module, traffic, ctime, from_des):
            index = message.path.index(link[0])
            node_src = message.path[index - 1]
            path, des = self.get_path(sim, message.app_name, message, node_src, alloc_DES, alloc_module,
                                      traffic, from_des)
            if len(path[0]) > 2:
                message.dst_int = path[0][2]
                return [message.path[0:message.path.index(path[0][0])] + path[0]], des
            return [], []

    population = PopAndFailures([5, 6, 9, 14], name="failures",
                                activation_dist=lib.distribution.exponentialDistributionStartPoint(
                                    30, 20.0, name="Failures"))
    population.set_sink_control({"ids": [0, 15], "number": 1, "module": app.get_sink_modules()})
    population.set_src_control({"number": 1, "message": app.get_message("M.Action"),
                                "distribution": lib.distribution.deterministic_distribution(5, name="D")})
    sim = lib.core.Sim(topology, default_results_path=results)
    sim.deploy_app2(app, lib.placement.NoPlacementOfModules("NoPlacement"), population, Nearest())
    sim.run(130)


# ----------------------------------------------------------------------------- JSON modelling


def json_modelling(lib: SimpleNamespace, results: str) -> None:
    topology = lib.topology.Topology()
    topology.load({
        "entity": [{"id": 0, "IPT": 400, "model": "cloud"}, {"id": 1, "IPT": 100}, {"id": 2, "IPT": 100},
                   {"id": 3, "IPT": 50}, {"id": 4, "IPT": 50}],
        "link": [{"s": 0, "d": 1, "BW": 0.002, "PR": 2}, {"s": 1, "d": 2, "BW": 0.01, "PR": 1},
                 {"s": 1, "d": 3, "BW": 1, "PR": 3}, {"s": 2, "d": 4, "BW": 1, "PR": 1}]})
    apps = lib.application.create_applications_from_json([
        {"name": "0", "module": [{"name": "C_0", "RAM": 0}, {"name": "A_0", "RAM": 4}],
         "message": [{"name": "MUC.0", "s": "None", "d": "C_0", "bytes": 3000, "instructions": 0},
                     {"name": "MCA.0", "s": "C_0", "d": "A_0", "bytes": 2000, "instructions": 40}],
         "transmission": [{"module": "C_0", "message_in": "MUC.0", "message_out": "MCA.0"},
                          {"module": "A_0", "message_in": "MCA.0"}]},
        {"name": "1", "module": [{"name": "C_1", "RAM": 0}],
         "message": [{"name": "MUC.1", "s": "None", "d": "C_1", "bytes": 5000, "instructions": 25}],
         "transmission": [{"module": "C_1", "message_in": "MUC.1"}]}])
    allocation = {"initialAllocation": [{"module_name": "C_0", "app": "0", "id_resource": 4},
                                        {"module_name": "A_0", "app": "0", "id_resource": 3},
                                        {"module_name": "C_1", "app": "1", "id_resource": 2}]}
    placement = lib.placement.JSONPlacementOnCloud(allocation, 0, name="OnCloud")

    class Users(lib.population.Population):
        def initial_allocation(self, sim, app_name):
            msg_name = f"MUC.{app_name}"
            message = sim.apps[app_name].get_message(msg_name)
            if app_name == "0":
                for seed, node in ((7, 3), (8, 3), (9, 4), (10, 0)):
                    sim.deploy_source(app_name, id_node=node, msg=message,
                                      distribution=lib.distribution.exponentialDistribution(name="Exp", lambd=40,
                                                                                            seed=seed))
            else:
                sim.deploy_source(app_name, id_node=3, msg=message,
                                  distribution=lib.distribution.uniformDistribution(min=5, max=30, name="U"))
                sim.deploy_source(app_name, id_node=3, msg=message,
                                  distribution=lib.distribution.deterministic_distribution(20, name="D"))

    class Shortest(lib.selection.Selection):
        def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
            des = alloc_module[app_name][message.dst][0]
            return [nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])], [des]

    sim = lib.core.Sim(topology, default_results_path=results)
    for name, app in apps.items():
        sim.deploy_app2(app, placement, Users(name=f"Users_{name}"), Shortest())
    sim.run(300)


SCENARIOS: dict[str, Callable[[SimpleNamespace, str], None]] = {
    "basic": basic,
    "service_movement": service_movement,
    "topology_changes": topology_changes,
    "user_movement": user_movement,
    "tutorial_main": tutorial_main,
    "vrgame": vrgame,
    "failures": failures,
    "json_modelling": json_modelling,
}

#: The global seed every scenario starts from.
SEED = 2


def run(name: str, package: str, results: str) -> None:
    """Seed the global generators, then run scenario ``name`` on ``package`` into ``results``."""
    random.seed(SEED)
    np.random.seed(SEED)
    SCENARIOS[name](library(package), results)
