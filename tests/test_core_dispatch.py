"""Redundant dispatch: N copies per request, per-copy outcomes, hooks and both deploy_app forms."""

from __future__ import annotations

import csv

import pytest
from yafs_examples.scenarios import (
    FixedPlacement,
    MulticastAll,
    UserPopulation,
    consume_app,
    edge_sim,
    line_topology,
)

from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.hooks import LinkDelay, ServiceModel, YAFSLinkDelay, YAFSServiceModel
from yafs_safetail.yafs.selection import Selection


def read_rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


class RefuseOn(YAFSServiceModel):
    def __init__(self, node):
        self.node = node

    def admit(self, sim, message, des, node, module):
        return node != self.node


def test_multicast_sends_one_copy_per_path_with_one_id_and_records_the_first_reply(tmp_path):
    sim, selection = edge_sim(tmp_path)
    heard = []
    sim.request_listeners.append(lambda s, outcome: heard.append(outcome))
    sim.run(150)
    assert len(selection.completed) == 1
    outcome = selection.completed[0]
    assert heard == [outcome]
    assert outcome.request_id == 1 and outcome.time_emit == 100
    assert [c.copy_index for c in outcome.copies] == [0, 1, 2]
    assert [c.dst_node for c in outcome.copies] == [2, 3, 4]
    assert [c.status for c in outcome.copies] == ["answered"] * 3
    # Uplink copies queue on the user's link; replies queue on the access point's downlink.
    assert [c.time_end - 100 for c in outcome.copies] == pytest.approx([4.006, 4.508, 5.01], abs=1e-9)
    assert outcome.first.copy_index == 0
    assert outcome.latency == pytest.approx(4.006, abs=1e-9)
    rows = read_rows(tmp_path / "edge.csv")
    assert {r["id"] for r in rows} == {"1"}
    assert [r["type"] for r in rows].count("COMP_M") == 3
    assert [r["type"] for r in rows].count("SINK_M") == 3


def test_refused_copy_produces_no_row_and_is_recorded(tmp_path):
    sim, selection = edge_sim(tmp_path, service_model=RefuseOn(3))
    sim.run(150)
    outcome = selection.completed[0]
    assert [c.status for c in outcome.copies] == ["answered", "refused", "answered"]
    assert outcome.copies[1].time_end == pytest.approx(102.003, abs=1e-9)
    assert outcome.refused == 1 and sim.refused_copies == 1
    assert outcome.first.copy_index == 0
    rows = read_rows(tmp_path / "edge.csv")
    assert all(r["TOPO.dst"] != "3" for r in rows)
    assert len(rows) == 4  # two services, two sink arrivals


def test_every_copy_refused_gives_no_first_reply(tmp_path):
    class RefuseAll(YAFSServiceModel):
        def admit(self, sim, message, des, node, module):
            return False

    sim, selection = edge_sim(tmp_path, service_model=RefuseAll())
    sim.run(250)
    assert len(selection.completed) == 2
    assert all(o.first is None and o.latency is None for o in selection.completed)
    assert sim.refused_copies == 6


def test_copies_ending_at_a_module_without_output_are_consumed(tmp_path):
    topology = line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 10.0})
    sim = Sim(topology, default_results_path=str(tmp_path / "c"))
    selection = MulticastAll()
    sim.deploy_app(consume_app(100, instructions=20), FixedPlacement("Svc", [1, 1]),
                   UserPopulation(0, "Req", 100), selection)
    sim.run(150)
    outcome = selection.completed[0]
    assert [c.status for c in outcome.copies] == ["consumed", "consumed"]
    assert outcome.first is None
    # Service ends: first copy 101.0001 + 2, second copy (waited on the link) 102.0002 + 2.
    assert [c.time_end for c in outcome.copies] == pytest.approx([103.0001, 104.0002], abs=1e-9)


class TwiceToFirstReplica(Selection):
    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        des = alloc_module[app_name][message.dst][0]
        return [[0, 1], [0, 1]], [des, des]


class NoQueues(YAFSLinkDelay):
    uses_link_queues = False


class Concurrent(YAFSServiceModel):
    concurrent = True

    def __init__(self):
        self.released = []

    def release(self, sim, message, des, node, module):
        self.released.append((message.copy_index, sim.env.now))


@pytest.mark.parametrize("concurrent", [False, True])
def test_fifo_versus_concurrent_service(tmp_path, concurrent):
    topology = line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 10.0})
    model = Concurrent() if concurrent else YAFSServiceModel()
    sim = Sim(topology, default_results_path=str(tmp_path / "s"), link_delay=NoQueues(),
              service_model=model)
    sim.deploy_app(consume_app(0, instructions=50), FixedPlacement("Svc", [1]),
                   UserPopulation(0, "Req", 100), TwiceToFirstReplica())
    sim.run(150)
    rows = read_rows(tmp_path / "s.csv")
    assert [float(r["time_reception"]) for r in rows] == [101.0, 101.0]  # no link queue
    expected_in = [101.0, 101.0] if concurrent else [101.0, 106.0]
    assert [float(r["time_in"]) for r in rows] == expected_in
    if concurrent:
        assert model.released == [(0, 106.0), (1, 106.0)]


def test_hooks_see_per_copy_fields_on_requests_and_replies(tmp_path):
    class Recording(YAFSLinkDelay):
        def __init__(self):
            self.seen = []

        def hop_delay_s(self, sim, message, src_node, dst_node):
            self.seen.append((message.name, message.copy_index, message.copy_dst_node, src_node, dst_node))
            return super().hop_delay_s(sim, message, src_node, dst_node)

    recording = Recording()
    sim, _ = edge_sim(tmp_path, link_delay=recording)
    assert isinstance(recording, LinkDelay) and isinstance(sim.service_model, ServiceModel)
    sim.run(150)
    replies = [s for s in recording.seen if s[0] == "Resp"]
    assert sorted({(s[1], s[2]) for s in replies}) == [(0, 2), (1, 3), (2, 4)]
    assert ("Resp", 1, 3, 3, 1) in replies and ("Resp", 1, 3, 1, 0) in replies


def test_set_hooks_after_construction(tmp_path):
    sim, selection = edge_sim(tmp_path)
    sim.set_service_model(RefuseOn(2))
    sim.set_link_delay(NoQueues())
    sim.run(150)
    outcome = selection.completed[0]
    assert outcome.copies[0].status == "refused"
    # Without link queues no copy waits: the fastest server (IPT 4000, copy 2) answers
    # after 0.501 + 1.001 + 0.25 + 1.002 + 0.502.
    assert outcome.first.copy_index == 2
    assert outcome.latency == pytest.approx(3.256, abs=1e-9)


def test_both_deploy_app_forms_give_the_same_rows(tmp_path):
    def build(form):
        topology = line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 10.0})
        sim = Sim(topology, default_results_path=str(tmp_path / form))
        app = consume_app(100, instructions=20)
        population = UserPopulation(0, "Req", 100)
        if form == "four":
            sim.deploy_app(app, FixedPlacement("Svc", [1]), population, MulticastAll())
        else:
            sim.deploy_app(app, FixedPlacement("Svc", [1]), MulticastAll())
            sim.deploy_source(app.name, id_node=0, msg=app.get_message("Req"),
                              distribution=deterministic_distribution(100))
        sim.run(450)
        return (tmp_path / f"{form}.csv").read_text(), (tmp_path / f"{form}_link.csv").read_text()

    four, three = build("four"), build("three")
    assert four == three
    assert len(four[0].splitlines()) == 1 + 4


def test_deploy_app_rejects_a_missing_selector(tmp_path):
    sim = Sim(line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 1.0}), write_results=False)
    with pytest.raises(TypeError):
        sim.deploy_app(consume_app(1), FixedPlacement("Svc", [1]))


def test_outcomes_without_result_files(tmp_path):
    sim, selection = edge_sim(tmp_path, write_results=False)
    sim.run(1000)
    assert len(selection.completed) == 9
    assert not (tmp_path / "edge.csv").exists()


def test_direct_engine_copies_to_stopped_processes_are_lost(tmp_path):
    topology = line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 10.0})
    sim = Sim(topology, write_results=False, engine="direct")
    selection = MulticastAll()
    sim.deploy_app(consume_app(100), FixedPlacement("Svc", [1, 1]), UserPopulation(0, "Req", 100), selection)
    sim.run(50)  # allocates the two replicas (process ids 1 and 2)
    sim.stop_process(2)
    sim.run(150)
    outcome = selection.completed[0]
    assert [c.status for c in outcome.copies] == ["consumed", "lost"]
    assert sim.lost_messages == 1


def test_yafs3_engine_stopped_process_serves_one_more_message_then_ends(tmp_path):
    # YAFS3's replica process checks "running" only between messages: stopped while it
    # waits on its pipe, it still serves the next message, then its loop ends and later
    # messages stay in its pipe (their copies never settle).
    topology = line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 10.0})
    sim = Sim(topology, default_results_path=str(tmp_path / "s"))
    selection = MulticastAll()
    sim.deploy_app(consume_app(100), FixedPlacement("Svc", [1, 1]), UserPopulation(0, "Req", 100), selection)
    sim.run(50)
    sim.stop_process(2)
    sim.run(350)
    rows = [r.split(",") for r in (tmp_path / "s.csv").read_text().splitlines()[1:]]
    assert [(r[0], r[6]) for r in rows] == [("1", "1"), ("1", "2"), ("2", "1"), ("3", "1")]
    assert [[c.status for c in o.copies] for o in selection.completed] == [["consumed", "consumed"]]


def test_failed_link_is_rerouted_by_the_selection(tmp_path):
    from yafs_safetail.yafs.path_routing import DeviceSpeedAwareRouting

    topology = line_topology([(0, 1, 1, 1), (1, 2, 1, 1), (1, 3, 1, 1), (3, 2, 1, 1)],
                             {0: 1.0, 1: 1.0, 2: 10.0, 3: 1.0})
    sim = Sim(topology, default_results_path=str(tmp_path / "f"))
    selection = DeviceSpeedAwareRouting()
    sim.deploy_app(consume_app(100), FixedPlacement("Svc", [2]), UserPopulation(0, "Req", 100), selection)
    # Remove the 1-2 link while the message is on its first hop.
    sim.deploy_monitor("cut", lambda: topology.G.remove_edge(1, 2), deterministic_distribution(100.5))
    sim.run(150)
    hops = [tuple(r.split(",")[2:4]) for r in (tmp_path / "f_link.csv").read_text().splitlines()[1:]]
    assert hops == [("0", "1"), ("1", "3"), ("3", "2")]
    assert len((tmp_path / "f.csv").read_text().splitlines()) == 2
