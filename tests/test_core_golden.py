"""YAFS's golden timings and rows (facts taken from YAFS's own committed example traces)."""

from __future__ import annotations

import csv

import networkx as nx
import pytest
from yafs_examples.scenarios import (
    FixedPlacement,
    MulticastAll,
    UserPopulation,
    consume_app,
    line_topology,
)

from yafs_safetail.yafs.application import Application, Message, fractional_selectivity
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.placement import Placement
from yafs_safetail.yafs.population import Statical
from yafs_safetail.yafs.selection import Selection
from yafs_safetail.yafs.topology import Topology


def read_rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def run_one_hop(tmp_path, size_bytes, bw, pr, replicas=1):
    """A user on node 0 sends one message at t=100 to ``replicas`` replicas on node 1."""
    topology = line_topology([(0, 1, bw, pr)], {0: 1.0, 1: 1.0})
    sim = Sim(topology, default_results_path=str(tmp_path / "hop"))
    sim.deploy_app(consume_app(size_bytes), FixedPlacement("Svc", [1] * replicas),
                   UserPopulation(0, "Req", 100), MulticastAll())
    sim.run(150)
    return read_rows(tmp_path / "hop.csv"), read_rows(tmp_path / "hop_link.csv")


@pytest.mark.parametrize(
    ("size_bytes", "bw", "pr", "expected"),
    [(1000, 1, 10, 10.001), (20, 1, 1, 1.00002)],
)
def test_one_hop_delay_is_bytes_over_bw_mega_plus_pr(tmp_path, size_bytes, bw, pr, expected):
    rows, links = run_one_hop(tmp_path, size_bytes, bw, pr)
    assert len(rows) == 1 and len(links) == 1
    assert float(rows[0]["time_reception"]) - 100.0 == pytest.approx(expected, abs=1e-9)
    assert float(links[0]["latency"]) == pytest.approx(expected, abs=1e-9)


def test_two_copies_on_one_link_queue_behind_each_other(tmp_path):
    rows, links = run_one_hop(tmp_path, 500, 1, 1, replicas=2)
    arrivals = sorted(float(r["time_reception"]) - 100.0 for r in rows)
    assert arrivals == pytest.approx([1.0005, 2.001], abs=1e-9)
    assert {r["id"] for r in rows} == {"1"}
    # Both hops start at the send time; the link row's latency excludes the wait.
    assert [(r["ctime"], r["latency"], r["buffer"]) for r in links] == [
        ("100", "1.0005", "0"), ("100", "1.0005", "1")]


class RoundRobinBroadcast(Selection):
    """The routing of YAFS's examples/Tutorial main2 (written here from its description)."""

    def __init__(self):
        self.next_index = {}

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        replicas = alloc_module[app_name][message.dst]
        if message.name == "M.A":
            index = self.next_index.get(message.dst, 0)
            self.next_index[message.dst] = (index + 1) % len(replicas)
            des = replicas[index]
            return [nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])], [des]
        return ([nx.shortest_path(sim.topology.G, topology_src, alloc_DES[d]) for d in replicas],
                list(replicas))


class OnCloud(Placement):
    def initial_allocation(self, sim, app_name):
        cloud = sim.topology.find_IDs({"mytag": "cloud"})
        app = sim.apps[app_name]
        for module, count in self.scaleServices.items():
            for _ in range(count):
                sim.deploy_module(app_name, module, app.services[module], cloud)


def main2_rows(tmp_path, sinks, replicas):
    app = Application(name="SimpleCase")
    app.set_modules([{"Sensor": {"Type": Application.TYPE_SOURCE}},
                     {"ServiceA": {"RAM": 10, "Type": Application.TYPE_MODULE}},
                     {"Actuator": {"Type": Application.TYPE_SINK}}])
    m_a = Message("M.A", "Sensor", "ServiceA", instructions=20 * 10**6, bytes=1000)
    m_b = Message("M.B", "ServiceA", "Actuator", instructions=30 * 10**6, bytes=500, broadcasting=True)
    app.add_source_messages(m_a)
    app.add_service_module("ServiceA", m_a, m_b, fractional_selectivity, threshold=1.0)
    topology = Topology()
    topology.load({
        "entity": [{"id": 0, "model": "cloud", "mytag": "cloud", "IPT": 5000 * 10**6},
                   {"id": 1, "model": "sensor-device", "IPT": 100 * 10**6},
                   {"id": 2, "model": "actuator-device", "IPT": 100 * 10**6}],
        "link": [{"s": 0, "d": 1, "BW": 1, "PR": 10}, {"s": 0, "d": 2, "BW": 1, "PR": 1}],
    })
    placement = OnCloud("onCloud")
    placement.scaleService({"ServiceA": replicas})
    population = Statical("Statical")
    population.set_sink_control({"model": "actuator-device", "number": sinks,
                                 "module": app.get_sink_modules()})
    population.set_src_control({"model": "sensor-device", "number": 1, "message": m_a,
                                "distribution": deterministic_distribution(name="D", time=100)})
    sim = Sim(topology, default_results_path=str(tmp_path / "sim_trace"))
    sim.deploy_app2(app, placement, population, RoundRobinBroadcast())
    sim.run(1000)
    return (
        (tmp_path / "sim_trace.csv").read_text().splitlines(),
        (tmp_path / "sim_trace_link.csv").read_text().splitlines(),
    )


def test_main2_rows_equal_yafs_committed_trace(tmp_path):
    # Rows copied as facts from YAFS's examples/Tutorial/results (one sink, one replica).
    events, links = main2_rows(tmp_path, sinks=1, replicas=1)
    assert events[1] == ("1,COMP_M,SimpleCase,ServiceA,M.A,0,2,1,0,Sensor,0.004,110.001,"
                         "110.00500000000001,100.0,110.001")
    assert events[2] == ("1,SINK_M,SimpleCase,Actuator,M.B,2,1,0,2,ServiceA,0,111.00550000000001,"
                         "111.00550000000001,110.00500000000001,111.00550000000001")
    assert events[4] == ("2,SINK_M,SimpleCase,Actuator,M.B,2,1,0,2,ServiceA,0,211.00549999999998,"
                         "211.00549999999998,210.005,211.00549999999998")
    assert links[1:3] == ["1,LINK,1,0,SimpleCase,10.001,M.A,100,1000,0",
                          "1,LINK,0,2,SimpleCase,1.0005,M.B,110.00500000000001,500,0"]
    assert len(events) == 1 + 2 * 9  # sources at 100..900; t=1000 is not simulated


def test_main2_with_two_sinks_second_copy_waits_for_the_link(tmp_path):
    events, _ = main2_rows(tmp_path, sinks=2, replicas=4)
    sinks = [row.split(",") for row in events[1:] if row.split(",")[0] == "1" and "SINK_M" in row]
    assert [float(r[14]) - 110.005 for r in sinks] == pytest.approx([1.0005, 2.001], abs=1e-9)
    assert [r[6] for r in sinks] == ["1", "2"]  # one copy per sink process


def test_tutorial01_style_rows_match_yafs_facts(tmp_path):
    # Facts from YAFS's tutorial_scenarios/01_basicExample trace: 20 B, BW=PR=1, IPT=100,
    # 30 instructions; users on nodes 1, 2, 4 reach node 0, a user on node 3 is served locally.
    topology = Topology()
    topology.G = nx.generators.binomial_tree(3)
    nx.set_edge_attributes(topology.G, name="PR", values=dict.fromkeys(topology.G.edges(), 1))
    nx.set_edge_attributes(topology.G, name="BW", values=dict.fromkeys(topology.G.edges(), 1))
    nx.set_node_attributes(topology.G, name="IPT", values=dict.fromkeys(topology.G.nodes(), 100))
    from yafs_safetail.yafs.application import create_applications_from_json
    from yafs_safetail.yafs.path_routing import DeviceSpeedAwareRouting
    from yafs_safetail.yafs.placement import JSONPlacement

    apps = create_applications_from_json([
        {"name": i, "module": [{"id": 1, "name": f"{i}_01", "type": "MODULE", "RAM": 1}],
         "message": [{"id": 0, "name": f"M.USER.APP.{i}", "s": "None", "d": f"{i}_01",
                      "bytes": 20, "instructions": 30}],
         "transmission": [{"message_in": f"M.USER.APP.{i}", "module": f"{i}_01"}]}
        for i in range(4)
    ])
    placement = JSONPlacement(name="P", json={"initialAllocation": [
        {"module_name": "0_01", "app": 0, "id_resource": 0},
        {"module_name": "1_01", "app": 1, "id_resource": 0},
        {"module_name": "2_01", "app": 2, "id_resource": 0},
        {"module_name": "2_01", "app": 2, "id_resource": 3},
        {"module_name": "3_01", "app": 3, "id_resource": 0}]})
    sim = Sim(topology, default_results_path=str(tmp_path / "t01"))
    selector = DeviceSpeedAwareRouting()
    for name in apps:
        sim.deploy_app(apps[name], placement, selector)
    for app_name, node in [(0, 1), (1, 2), (2, 3), (3, 4)]:
        msg = sim.apps[app_name].get_message(f"M.USER.APP.{app_name}")
        sim.deploy_source(app_name, id_node=node, msg=msg,
                          distribution=deterministic_distribution(100, name="Deterministic"))
    sim.run(300)
    events = (tmp_path / "t01.csv").read_text().splitlines()
    links = (tmp_path / "t01_link.csv").read_text().splitlines()
    assert events[1:5] == [
        "3,COMP_M,2,2_01,M.USER.APP.2,2,7,3,3,None,0.3,100,100.3,100.0,100.0",
        "1,COMP_M,0,0_01,M.USER.APP.0,0,4,1,0,None,0.3,101.00002,101.30002,100.0,101.00002",
        "2,COMP_M,1,1_01,M.USER.APP.1,1,5,2,0,None,0.3,101.00002,101.30002,100.0,101.00002",
        "4,COMP_M,3,3_01,M.USER.APP.3,3,8,4,0,None,0.3,101.00002,101.30002,100.0,101.00002",
    ]
    assert "5,COMP_M,0,0_01,M.USER.APP.0,0,4,1,0,None,0.3,201.00002,201.30002000000002,200.0,201.00002" in events
    assert links[1:4] == ["1,LINK,1,0,0,1.00002,M.USER.APP.0,100,20,0",
                          "2,LINK,2,0,1,1.00002,M.USER.APP.1,100,20,1",
                          "4,LINK,4,0,3,1.00002,M.USER.APP.3,100,20,2"]
