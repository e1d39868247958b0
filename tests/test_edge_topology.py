"""Topology and placement files: shipped variants load, bad input gets one clear error."""

import copy
import json
from pathlib import Path

import pytest

from yafs_safetail.edge.scenario import load_placement, load_scenario
from yafs_safetail.edge.topology_io import ScenarioError, load_topology

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = {"paper_5servers": 5, "3servers": 3, "7servers": 7}


@pytest.mark.parametrize("name,n", sorted(VARIANTS.items()))
def test_shipped_topologies_load(name, n):
    scenario = load_scenario(
        ROOT / "topologies" / f"{name}.json",
        ROOT / "placements" / f"{name}.json",
        known_conditions=range(1, 6),
        n_load_devices=10,
    )
    assert scenario.n_servers == n
    assert all(1 <= c <= 5 for c in scenario.server_conditions)
    assert scenario.server_load_devices == tuple(range(n))
    assert scenario.user_node not in scenario.server_nodes


def _paper():
    topo = json.loads((ROOT / "topologies" / "paper_5servers.json").read_text())
    place = json.loads((ROOT / "placements" / "paper_5servers.json").read_text())
    return topo, place


def test_server_order_follows_placement():
    topo, place = _paper()
    place["initialAllocation"].reverse()
    scenario = load_scenario(topo, place)
    assert scenario.server_nodes == (6, 5, 4, 3, 2)
    assert scenario.server_conditions == (5, 4, 3, 2, 1)


def test_missing_file_names_the_file(tmp_path):
    with pytest.raises(ScenarioError, match="nope.json: file: topology file not found"):
        load_topology(tmp_path / "nope.json")


def test_invalid_json_names_file_and_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"entity": [\n}')
    with pytest.raises(ScenarioError, match=r"bad.json: line 2: invalid JSON"):
        load_topology(bad)


def _mutated(mutate):
    topo, place = _paper()
    topo, place = copy.deepcopy(topo), copy.deepcopy(place)
    mutate(topo, place)
    return topo, place


CASES = [
    (lambda t, p: t["link"][1].update(condition=9), r"link to edge server 2\.condition: unknown distance condition 9"),
    (lambda t, p: t["link"][2].pop("condition"), r"link\[2\]\.condition: missing"),
    (lambda t, p: t["entity"][2].update(load_device=12), r"edge server 2\.load_device: unknown load device 12"),
    (lambda t, p: t["entity"][3].update(load_device=-1), r"entity\[3\]\.load_device"),
    (lambda t, p: p["initialAllocation"].pop(), r"4 servers placed but .* has 5 edge servers"),
    (lambda t, p: p["initialAllocation"][0].update(id_resource=1), r"initialAllocation\[0\]\.id_resource: node 1 is not an edge_server"),
    (lambda t, p: p["initialAllocation"][1].update(id_resource=2), r"initialAllocation\[1\]\.id_resource: node 2 listed twice"),
    (lambda t, p: p["initialAllocation"][1].update(app="Other"), r"initialAllocation: every entry must deploy the same app"),
    (lambda t, p: t["entity"][0].update(type="robot"), r"entity\[0\]\.type: got 'robot'"),
    (lambda t, p: t["entity"][1].update(type="user"), r"entity\.type: expected exactly one 'user'"),
    (lambda t, p: t["link"][0].update(BW=0), r"link\[0\]\.BW: missing or not a positive number"),
    (lambda t, p: t["link"][3].update(d=99), r"link\[3\]\.d: unknown node id 99"),
    (lambda t, p: t["link"].pop(0), r"link: no link between the user and the access point"),
    (lambda t, p: t["entity"][0].update(x="far"), r"entity\[0\]\.x: not a finite number"),
]


@pytest.mark.parametrize("mutate,message", CASES)
def test_bad_scenario_gets_one_line_error(mutate, message):
    topo, place = _mutated(mutate)
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(topo, place, known_conditions=range(1, 6), n_load_devices=10)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)


def test_placement_from_file_names_file(tmp_path):
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"initialAllocation": [{"module_name": "M", "app": "A"}]}))
    with pytest.raises(ScenarioError, match=r"p\.json: initialAllocation\[0\]\.id_resource"):
        load_placement(path)
