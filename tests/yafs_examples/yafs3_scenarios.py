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

import random
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import networkx as nx
import numpy as np

from yafs_examples.yafs3_common import _one_module_apps, _unit_graph, library
from yafs_examples.yafs3_example_scenarios import failures, json_modelling, vrgame


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
