"""YAFS3's public names used by its tutorials and examples, with YAFS3's behaviour.

Where the core keeps a different behaviour it is an explicit option (``engine="direct"``,
``graph=True``, ``sink_module_list``, ...), checked here next to the YAFS3 default.
"""

from __future__ import annotations

import random
import warnings

import networkx as nx
import numpy as np
import pandas as pd
import pytest
from yafs_examples.scenarios import (
    FixedPlacement,
    MulticastAll,
    UserPopulation,
    consume_app,
    line_topology,
)

import yafs_safetail.yafs as yafs
from yafs_safetail.yafs import action, distribution, placement, population
from yafs_safetail.yafs.application import Application, Message
from yafs_safetail.yafs.core import EVENT_DOWN_ENTITY, EVENT_UP_ENTITY, Sim
from yafs_safetail.yafs.hooks import YAFSLinkDelay, YAFSServiceModel
from yafs_safetail.yafs.metrics import Metrics
from yafs_safetail.yafs.selection import First_ShortestPath, OneRandomPath, Selection
from yafs_safetail.yafs.stats import Stats
from yafs_safetail.yafs.topology import Topology

GOLDEN = __import__("pathlib").Path(__file__).resolve().parent / "golden" / "yafs3"


# ----------------------------------------------------------------------------- names


def test_star_imports_give_yafs3s_names():
    names: dict = {}
    exec("from yafs_safetail.yafs.placement import *", names)  # noqa: S102 - YAFS scripts do this
    assert {"Placement", "JSONPlacement", "JSONPlacementOnCloud", "ClusterPlacement", "EdgePlacement",
            "NoPlacementOfModules"} <= names.keys()
    exec("from yafs_safetail.yafs.distribution import *", names)  # noqa: S102
    assert {"deterministic_distribution", "deterministicDistributionStartPoint", "exponential_distribution",
            "exponentialDistribution", "exponentialDistributionStartPoint", "uniformDistribution"} <= names.keys()
    exec("from yafs_safetail.yafs.population import *", names)  # noqa: S102
    assert {"Population", "Statical"} <= names.keys()
    for name in ("Sim", "Placement", "ClusterPlacement", "Selection", "OneRandomPath", "First_ShortestPath",
                 "Topology", "Population", "Statical", "Application", "Message", "Metrics"):
        assert hasattr(yafs, name), name


def test_policies_have_a_logger():
    assert placement.NoPlacementOfModules("n").logger is not None
    assert population.Population("p").logger is not None
    assert placement.JSONPlacement({"initialAllocation": []}, name="j").logger is not None


def test_metrics_names_and_action():
    assert (Metrics.TIME_LATENCY, Metrics.TIME_WAIT, Metrics.TIME_RESPONSE, Metrics.TIME_SERVICE,
            Metrics.TIME_TOTAL_RESPONSE) == ("time_latency", "time_wait", "time_response", "time_service",
                                             "time_total_response")
    assert (Metrics.WATT_SERVICE, Metrics.WATT_UPTIME) == ("byService", "byUptime")
    sim = object()
    act = action.generic_action(sim)
    assert act.sim is sim and act.action("agent") is None


# ----------------------------------------------------------------------------- application


def test_get_sink_modules_is_yafs3s_last_sink_name():
    app = Application("a")
    assert app.get_sink_modules() == []
    app.set_modules([{"S": {"Type": Application.TYPE_SOURCE}}, {"Display": {"Type": Application.TYPE_SINK}},
                     {"Play": {"Type": Application.TYPE_MODULE}}, {"Log": {"Type": Application.TYPE_SINK}}])
    assert app.get_sink_modules() == "Log"
    assert app.sink_module_list() == ["Display", "Log"]
    # YAFS's test is "in": with one sink name it is a substring test ("Play" is in "Display"
    # only while Display is the last sink).
    assert app.get_pure_modules() == ["Display", "Play"]


# ----------------------------------------------------------------------------- topology


def test_topology_loaders(tmp_path):
    graph = nx.path_graph(3)
    nx.write_graphml(graph, tmp_path / "g.graphml")
    topology = Topology()
    topology.load_graphml(tmp_path / "g.graphml")
    assert sorted(topology.G.nodes) == ["0", "1", "2"]
    assert all(d == {"BW": 1, "PR": 1} for _, _, d in topology.G.edges(data=True))
    assert topology.get_nodes_att() == {"0": {"IPT": 1}, "1": {"IPT": 1}, "2": {"IPT": 1}}
    topology.create_random_topology(nx.generators.binomial_tree, (2,))
    assert topology.size() == 4
    with pytest.raises(TypeError):
        topology.create_topology_from_graph([(0, 1)])
    topology.create_topology_from_graph(graph)
    assert topology.G is graph


def test_topology_entities_as_yafs3_keeps_them():
    topology = Topology()
    topology.load({"entity": [{"id": 0, "model": "cloud", "IPT": 5}, {"id": 1, "model": "m-"},
                              {"id": 9, "model": "m-"}],
                   "link": [{"s": 0, "d": 1, "BW": 1, "PR": 1}]})
    assert topology.get_nodes_att()[0] == {"id": 0, "model": "cloud", "IPT": 5, "uptime": (0, None)}
    assert topology.G.nodes[1]["IPT"] == 0  # YAFS: an entity without IPT gets 0
    assert topology.find_IDs({"model": "m-"}) == [1, 9]  # entities, linked or not (YAFS)
    assert topology.find_IDs({"model": "m-"}, graph=True) == [1]
    assert list(topology.get_edges()) == [(0, 1)]
    bare = Topology()
    bare.G = nx.path_graph(2)
    nx.set_node_attributes(bare.G, "m-", "model")
    assert bare.find_IDs({"model": "m-"}) == [] and bare.find_IDs({"model": "m-"}, graph=True) == [0, 1]


# ----------------------------------------------------------------------------- engines


def test_engine_is_yafs3_unless_custom_hooks():
    topology = line_topology([(0, 1, 1, 1)], {0: 1, 1: 1})
    assert Sim(topology, write_results=False).engine == "yafs3"
    assert Sim(topology, write_results=False, link_delay=YAFSLinkDelay()).engine == "yafs3"

    class Concurrent(YAFSServiceModel):
        concurrent = True

    assert Sim(topology, write_results=False, service_model=Concurrent()).engine == "direct"
    assert Sim(topology, write_results=False, engine="direct").engine == "direct"
    with pytest.raises(ValueError, match="engine"):
        Sim(topology, engine="fast")
    with pytest.raises(ValueError, match="concurrent"):
        Sim(topology, service_model=Concurrent(), engine="yafs3")


def deployed(engine, replicas_on_node_1=2):
    topology = line_topology([(0, 1, 1, 1), (1, 2, 1, 1)], {0: 1, 1: 1, 2: 1})
    sim = Sim(topology, write_results=False, engine=engine)
    sim.deploy_app(consume_app(10), FixedPlacement("Svc", [1] * replicas_on_node_1 + [2]),
                   UserPopulation(1, "Req", 100), MulticastAll())
    sim.run(10)
    return sim


@pytest.mark.parametrize(("engine", "left"), [("yafs3", [2, 3]), ("direct", [3])])
def test_undeploy_all_modules(engine, left):
    # Process ids: 0 the user on node 1, then replicas 1 and 2 on node 1 and 3 on node 2.
    sim = deployed(engine)
    sim.undeploy_all_modules("consume", "Svc", 1)
    # YAFS3 removes from the list it walks, skipping the replica after each one removed.
    assert sim.alloc_module["consume"]["Svc"] == left


@pytest.mark.parametrize(("engine", "left_on_node_1"), [("yafs3", [1, 2]), ("direct", [])])
def test_remove_node(engine, left_on_node_1):
    sim = deployed(engine)
    sim.remove_node(1)
    assert 1 not in sim.topology.G
    # YAFS3 forgets only the first process found on the node (the user, id 0).
    assert [des for des, node in sim.alloc_DES.items() if node == 1] == left_on_node_1
    assert 0 not in sim.alloc_DES
    assert (0 in sim.alloc_source) is (engine == "yafs3")


def test_yafs3_alloc_entities_list_sources_where_they_were_deployed():
    sim = deployed("yafs3")
    sim.alloc_DES[0] = 2  # a user moved by a script, as YAFS3's tutorial 04 does
    assert sim.get_alloc_entities()[1].count("consume#None") == 1
    assert deployed("direct").get_alloc_entities()[1].count("consume#None") == 1


def test_entity_processes_and_the_stop_monitor_take_ids():
    topology = line_topology([(0, 1, 1, 1)], {0: 1, 1: 1})
    sim = Sim(topology, write_results=False)
    sim.register_event_entity(lambda: 50, EVENT_UP_ENTITY)
    sim.register_event_entity(lambda: 50, EVENT_DOWN_ENTITY)
    sim.run(10)
    # Ids taken when the processes start: 0 and 1, then 2 by the stop monitor.
    assert sim.deploy_sink("x", node=0, module="S") == 3
    assert sim.des_process_running[1] is True and 0 not in sim.des_process_running


def test_yafs3_run_without_until_ends_when_nothing_is_left():
    topology = line_topology([(0, 1, 1, 1)], {0: 1, 1: 1})
    sim = Sim(topology, write_results=False)
    sim.deploy_monitor("once", lambda: None, distribution.deterministicDistributionStartPoint(5, 10))
    sim.run(20)
    sim.stop_process(sim.get_DES("once"))
    sim.run(None)  # YAFS3's stop monitor would keep this running forever
    assert sim.env.now >= 20


def test_network_pump_and_entity_metrics():
    topology = line_topology([(0, 1, 1, 10)], {0: 1, 1: 1})
    sim = Sim(topology, write_results=False)
    sim.deploy_app(consume_app(10), FixedPlacement("Svc", [1]), UserPopulation(0, "Req", 100), MulticastAll())
    sim.run(105)
    assert sim.network_pump == 1  # the request sent at 100 is on the link until 110
    assert sim.entity_metrics == {"node": {0: {}, 1: {}}, "link": {(0, 1): {"PR": 10, "BW": 1}}}


# ----------------------------------------------------------------------------- selections


def test_selection_base_sends_nothing_and_has_yafs_attributes():
    selection = Selection()
    assert selection.get_path(None, "a", None, 0, {}, {}, {}, 0) == ([], [])
    assert (selection.transmit, selection.lat_acc, selection.propagation) == (0.0, 0.0, 0.0)


def test_first_shortest_path_uses_the_last_replica():
    topology = line_topology([(0, 1, 1, 1), (1, 2, 1, 1)], {0: 1, 1: 1, 2: 1})
    sim = Sim(topology, write_results=False)
    msg = Message("Req", "None", "Svc")
    alloc_module = {"a": {"Svc": [7, 8]}}
    paths, des = First_ShortestPath().get_path(sim, "a", msg, 0, {7: 1, 8: 2}, alloc_module, {}, 0)
    assert (paths, des) == ([[0, 1, 2]], [8])


def test_one_random_path_draws_from_the_global_generator():
    graph = nx.cycle_graph(4)
    topology = Topology()
    topology.G = graph
    sim = Sim(topology, write_results=False)
    msg = Message("Req", "None", "Svc")
    state = random.getstate()
    try:
        random.seed(3)
        first = OneRandomPath().get_path(sim, "a", msg, 0, {5: 2, 6: 3}, {"a": {"Svc": [5, 6]}}, {}, 0)
        random.seed(3)
        again = OneRandomPath().get_path(sim, "a", msg, 0, {5: 2, 6: 3}, {"a": {"Svc": [5, 6]}}, {}, 0)
    finally:
        random.setstate(state)
    assert first == again and first[1] == [5, 6]
    assert first[0][0] in ([0, 1, 2], [0, 3, 2]) and first[0][1] in ([0, 1, 2, 3], [0, 3])


# ----------------------------------------------------------------------------- placements


def test_placements_of_yafs3():
    topology = Topology()
    topology.load({"entity": [{"id": 0, "model": "Cluster", "IPT": 10}, {"id": 1, "model": "d-", "IPT": 10},
                              {"id": 2, "model": "m-", "IPT": 10}],
                   "link": [{"s": 0, "d": 1, "BW": 1, "PR": 1}, {"s": 1, "d": 2, "BW": 1, "PR": 1}]})
    app = Application("g")
    app.set_modules([{m: {"Type": Application.TYPE_MODULE}} for m in ("Coordinator", "Calculator", "Client")])
    for module in ("Coordinator", "Calculator", "Client"):
        app.add_service_module(module, Message(f"to{module}", "x", module))

    def placed(policy):
        sim = Sim(topology, write_results=False)
        sim.deploy_app(app, policy, MulticastAll())
        sim.run(1)
        return {m: [sim.alloc_DES[d] for d in ds] for m, ds in sim.alloc_module["g"].items()}

    cluster = placement.ClusterPlacement("c")
    cluster.scaleService({"Coordinator": 1, "Calculator": 2})
    assert placed(cluster) == {"Coordinator": [0], "Calculator": [0, 0], "Client": [2]}
    assert placed(placement.EdgePlacement("e")) == {"Coordinator": [0], "Calculator": [1], "Client": [2]}
    assert placed(placement.NoPlacementOfModules("n")) == {}
    on_cloud = placement.JSONPlacementOnCloud({"initialAllocation": [
        {"module_name": "Client", "app": "g", "id_resource": 2}]}, 1, name="j")
    assert placed(on_cloud) == {"Client": [1]}


# ----------------------------------------------------------------------------- stats


@pytest.fixture
def stats():
    return Stats(defaultPath=str(GOLDEN / "vrgame"))


def test_stats_counts_as_yafs3(stats):
    links = pd.read_csv(GOLDEN / "vrgame_link.csv")
    assert stats.count_messages() == len(links)  # YAFS3 counts hops
    assert stats.bytes_transmitted() == links["size"].sum()
    assert stats.peak_messages_not_transmitted() == links["buffer"].max()
    assert stats.average_messages_not_transmitted() == pytest.approx(links["buffer"].mean())
    last = stats.messages_not_transmitted()
    assert isinstance(last, pd.Series) and list(last) == [links["buffer"].iloc[-1]]


def test_stats_loops(stats, capsys):
    events = pd.read_csv(GOLDEN / "vrgame.csv")
    total = (events["time_out"] - events["time_reception"]) + (events["time_reception"] - events["time_emit"])
    means = total.groupby(events["message"]).mean()
    loop = ["M.EGG", "M.Sensor", "M.Concentration", "M.Absent"]
    expected = means["M.EGG"] + means["M.Sensor"] + means["M.Concentration"]
    assert stats.average_loop_response([loop]) == [pytest.approx(expected)]
    assert stats.valueLoop(450, time_loops=[loop]) == pytest.approx(expected)
    assert stats.valueLoop(450) is None
    stats.showLoops([loop])
    assert f"0 - {loop!s} :\t {expected:f}" in capsys.readouterr().out


def test_stats_energy_and_reports(stats, capsys):
    topology = Topology()
    topology.load({"entity": [{"id": n, "model": "m", "WATT": 2.0, "COST": 1.5} for n in range(20)],
                   "link": [{"s": n, "d": n + 1, "BW": 1, "PR": 1} for n in range(19)]})
    by_service = stats.get_watt(450, topology, Metrics.WATT_SERVICE)
    served = pd.read_csv(GOLDEN / "vrgame.csv").assign(
        s=lambda d: d.time_out - d.time_in).groupby("TOPO.dst")["s"].sum()
    assert set(by_service) == set(served.index)
    assert by_service[0]["watt"] == pytest.approx(served[0] * 2.0)
    by_uptime = stats.get_watt(450, topology, Metrics.WATT_UPTIME)
    assert by_uptime[3] == {"model": "m", "type": None, "watt": 900.0, "uptime": 450}
    total, _ = stats.get_cost_cloud(topology)
    assert total == pytest.approx(served.sum() * 1.5)
    stats.showResults(450, topology, time_loops=[["M.EGG"]])
    out = capsys.readouterr().out
    assert "Simulation Time: 450.00" in out and "Network bytes transmitted:" in out
    modules = stats.get_df_modules()
    assert list(modules.columns.get_level_values(0)[:2]) == ["module", "DES.dst"]
    utilisation = stats.get_df_service_utilization("Client", 450)
    assert (utilisation["utilization"] > 0).all()


# ----------------------------------------------------------------------------- distributions


def test_exponential_distribution_old_name_warns_and_draws_the_same():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = distribution.exponentialDistribution(name="E", lambd=10, seed=4)
    assert caught and issubclass(caught[0].category, FutureWarning)
    new = distribution.exponential_distribution(10, seed=4)
    assert [old.next() for _ in range(600)] == [new.next() for _ in range(600)]  # past one block
    reference = np.random.RandomState(4)
    assert [new.next() for _ in range(5)] == [
        max(int(v), 1) for v in reference.exponential(10, size=605)[600:]]


def test_device_speed_aware_routing_sees_graph_changes():
    from yafs_safetail.yafs.path_routing import DeviceSpeedAwareRouting

    topology = Topology()
    topology.G = nx.path_graph(5)
    sim = Sim(topology, write_results=False)
    msg = Message("Req", "None", "Svc")
    routing = DeviceSpeedAwareRouting()
    alloc_module = {"a": {"Svc": [9]}}
    first = routing.get_path(sim, "a", msg, 0, {9: 4}, alloc_module, {}, 0)
    assert first == ([[0, 1, 2, 3, 4]], [9])
    first[0][0].append("mutated by a caller")
    assert routing.get_path(sim, "a", msg, 0, {9: 4}, alloc_module, {}, 0)[0] == [[0, 1, 2, 3, 4]]
    topology.G.add_edge(0, 4)  # a shortcut: networkx empties its cache, the route follows
    assert routing.get_path(sim, "a", msg, 0, {9: 4}, alloc_module, {}, 0)[0] == [[0, 4]]
    topology.G.remove_node(4)
    assert routing.get_path(sim, "a", msg, 0, {9: 4}, alloc_module, {}, 0) == ([], None)


@pytest.mark.parametrize(("engine", "created"), [("yafs3", True), ("direct", False)])
def test_result_files_are_created_with_the_sim_as_yafs3(tmp_path, engine, created):
    topology = line_topology([(0, 1, 1, 1)], {0: 1, 1: 1})
    sim = Sim(topology, default_results_path=str(tmp_path / "r"), engine=engine)
    assert (tmp_path / "r.csv").exists() is created
    assert (tmp_path / "r_link.csv").exists() is created
    sim.run(1)
    assert (tmp_path / "r.csv").read_text().startswith("id,type,app,module,message,DES.src")


def test_yafs3_engine_with_a_custom_link_delay_sees_copy_fields(tmp_path):
    from yafs_examples.scenarios import ReplyToSender, request_reply_app

    class Recording(YAFSLinkDelay):
        def __init__(self):
            self.seen = []

        def hop_delay_s(self, sim, message, src_node, dst_node):
            self.seen.append((message.name, message.copy_index, message.copy_dst_node))
            return super().hop_delay_s(sim, message, src_node, dst_node) + 0.5

    delay = Recording()
    topology = line_topology([(0, 1, 1.0, 0.5), (1, 2, 1.0, 1.0), (1, 3, 1.0, 1.0)], {0: 1, 1: 1, 2: 50, 3: 50})
    sim = Sim(topology, default_results_path=str(tmp_path / "c"), link_delay=delay, engine="yafs3")
    selection = ReplyToSender()
    sim.deploy_app(request_reply_app(1000, 2000, 100.0), FixedPlacement("Svc", [2, 3]),
                   UserPopulation(0, "Req", 100, sink="Client"), selection)
    sim.run(150)
    assert sorted(set(delay.seen)) == [("Req", 0, 2), ("Req", 1, 3), ("Resp", 0, 2), ("Resp", 1, 3)]
    (outcome,) = selection.completed
    assert [c.status for c in outcome.copies] == ["answered", "answered"]
    # The custom delay (+0.5 per hop) is in the rows: 0.501 + 0.5 on the first hop.
    first_hop = (tmp_path / "c_link.csv").read_text().splitlines()[1].split(",")
    assert float(first_hop[5]) == pytest.approx(1000 / 1e6 + 0.5 + 0.5)
