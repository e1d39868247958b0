"""The scenarios in the spirit of YAFS3's examples/ folder (vrgame, failures, json_modelling);
see yafs3_scenarios.py for what each exercises."""

from __future__ import annotations

import random
from types import SimpleNamespace

import networkx as nx

from yafs_examples.yafs3_common import _unit_graph


def vrgame(lib: SimpleNamespace, results: str) -> None:
    # Long on purpose: it reads as the YAFS3 example script it mirrors, top to bottom.
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
    # Long on purpose: it reads as the YAFS3 example script it mirrors, top to bottom.
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
