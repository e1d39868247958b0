"""Bad YAFS inputs raise one clear YAFSInputError naming the file, the entry and the field."""

from __future__ import annotations

import json

import pytest
from yafs_examples.scenarios import MulticastAll, consume_app, line_topology

from yafs_safetail.yafs.application import create_applications_from_json
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.errors import YAFSInputError
from yafs_safetail.yafs.placement import JSONPlacement
from yafs_safetail.yafs.population import JSONPopulation
from yafs_safetail.yafs.topology import Topology

GOOD_TOPOLOGY = {
    "entity": [{"id": 0, "IPT": 1}, {"id": 1, "IPT": 10}],
    "link": [{"s": 0, "d": 1, "BW": 1, "PR": 1}],
}
GOOD_APP = [{
    "name": "a",
    "module": [{"name": "Svc", "RAM": 1}],
    "message": [{"name": "Req", "s": "None", "d": "Svc", "bytes": 10, "instructions": 5}],
    "transmission": [{"module": "Svc", "message_in": "Req"}],
}]


def write(tmp_path, name, content):
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


def assert_clear(excinfo, *fragments):
    text = str(excinfo.value)
    assert isinstance(excinfo.value, ValueError)
    assert "\n" not in text
    for fragment in fragments:
        assert fragment in text, text


def mutated(document, mutate):
    copy = json.loads(json.dumps(document))
    mutate(copy)
    return copy


@pytest.mark.parametrize(
    ("mutate", "fragments"),
    [
        (lambda d: d.pop("link"), ["field 'link'", "missing required key"]),
        (lambda d: d["link"][0].pop("BW"), ["link[0]", "field 'BW'", "missing"]),
        (lambda d: d["link"][0].update(BW="fast"), ["link[0]", "field 'BW'", "expected a number"]),
        (lambda d: d["link"][0].update(BW=-1), ["link[0]", "field 'BW'", "positive"]),
        (lambda d: d["link"][0].update(PR=-0.5), ["link[0]", "field 'PR'", "non-negative"]),
        (lambda d: d["entity"][1].update(IPT=-3), ["entity[1]", "field 'IPT'", "positive"]),
        (lambda d: d["link"][0].update(d=7), ["link[0]", "field 'd'", "not an entity"]),
        (lambda d: d["entity"][0].update(id=[1]), ["entity[0]", "field 'id'"]),
        (lambda d: d.update(entity={}), ["field 'entity'", "expected a list"]),
    ],
)
def test_bad_topology(tmp_path, mutate, fragments):
    path = write(tmp_path, "net.json", mutated(GOOD_TOPOLOGY, mutate))
    with pytest.raises(YAFSInputError) as excinfo:
        Topology().load(path)
    assert_clear(excinfo, "net.json", *fragments)


def test_topology_file_that_is_not_json(tmp_path):
    path = write(tmp_path, "net.json", '{"entity": [')
    with pytest.raises(YAFSInputError) as excinfo:
        Topology().load(path)
    assert_clear(excinfo, "net.json", "not valid JSON")


def test_topology_dict_errors_name_the_input_kind():
    with pytest.raises(YAFSInputError) as excinfo:
        Topology().load({"entity": []})
    assert_clear(excinfo, "topology", "field 'link'")


@pytest.mark.parametrize(
    ("mutate", "fragments"),
    [
        (lambda d: d[0].pop("message"), ["app 'a'", "field 'message'", "missing"]),
        (lambda d: d[0]["message"][0].update(bytes=-1), ["message[0]", "field 'bytes'", "non-negative"]),
        (lambda d: d[0]["message"][0].update(instructions="x"), ["message[0]", "field 'instructions'"]),
        (lambda d: d[0]["message"][0].update(d="Nope"), ["message[0]", "field 'd'", "'Nope'"]),
        (lambda d: d[0]["transmission"][0].update(module="Nope"), ["transmission[0]", "field 'module'"]),
        (lambda d: d[0]["transmission"][0].update(message_in="Nope"),
         ["transmission[0]", "field 'message_in'", "'Nope'"]),
        (lambda d: d[0].update(module={"name": "Svc"}), ["field 'module'", "expected a list"]),
    ],
)
def test_bad_application(tmp_path, mutate, fragments):
    path = write(tmp_path, "apps.json", mutated(GOOD_APP, mutate))
    with pytest.raises(YAFSInputError) as excinfo:
        create_applications_from_json(path)
    assert_clear(excinfo, "apps.json", *fragments)


def test_application_file_that_is_not_json(tmp_path):
    with pytest.raises(YAFSInputError) as excinfo:
        create_applications_from_json(write(tmp_path, "apps.json", "[{"))
    assert_clear(excinfo, "apps.json", "not valid JSON")


def placed_sim(placement):
    sim = Sim(line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 1.0}), write_results=False)
    sim.deploy_app(consume_app(10), placement, MulticastAll())
    return sim


@pytest.mark.parametrize(
    ("entry", "fragments"),
    [
        ({"module_name": "Svc", "app": "consume", "id_resource": 9},
         ["initialAllocation[0]", "field 'id_resource'", "not in the topology"]),
        ({"module_name": "Nope", "app": "consume", "id_resource": 1},
         ["initialAllocation[0]", "field 'module_name'", "'Nope'"]),
        ({"module_name": "Svc", "app": "other", "id_resource": 1},
         ["initialAllocation[0]", "field 'app'", "'other'"]),
    ],
)
def test_placement_naming_missing_things(tmp_path, entry, fragments):
    path = write(tmp_path, "alloc.json", {"initialAllocation": [entry]})
    sim = placed_sim(JSONPlacement(path, name="p"))
    with pytest.raises(YAFSInputError) as excinfo:
        sim.run(10)
    assert_clear(excinfo, "alloc.json", *fragments)


@pytest.mark.parametrize(
    ("content", "fragments"),
    [
        ("{", ["not valid JSON"]),
        ({"allocation": []}, ["field 'initialAllocation'", "missing"]),
        ({"initialAllocation": [{"module_name": "Svc", "app": "consume"}]},
         ["initialAllocation[0]", "field 'id_resource'", "missing"]),
    ],
)
def test_malformed_placement(tmp_path, content, fragments):
    with pytest.raises(YAFSInputError) as excinfo:
        JSONPlacement(write(tmp_path, "alloc.json", content))
    assert_clear(excinfo, "alloc.json", *fragments)


@pytest.mark.parametrize(
    ("content", "fragments"),
    [
        ("[", ["not valid JSON"]),
        ({"sources": [{"id_resource": 0, "app": "consume", "message": "Req", "lambda": -2}]},
         ["sources[0]", "field 'lambda'", "positive"]),
        ({"sources": [{"id_resource": 0, "app": "consume", "lambda": 2}]},
         ["sources[0]", "field 'message'", "missing"]),
        ({"sources": {}}, ["field 'sources'", "expected a list"]),
    ],
)
def test_malformed_population(tmp_path, content, fragments):
    with pytest.raises(YAFSInputError) as excinfo:
        JSONPopulation(write(tmp_path, "users.json", content))
    assert_clear(excinfo, "users.json", *fragments)


@pytest.mark.parametrize(
    ("source", "fragments"),
    [
        ({"id_resource": 5, "app": "consume", "message": "Req", "lambda": 2},
         ["sources[0]", "field 'id_resource'", "not in the topology"]),
        ({"id_resource": 0, "app": "consume", "message": "Nope", "lambda": 2},
         ["sources[0]", "field 'message'", "'Nope'"]),
    ],
)
def test_population_naming_missing_things(tmp_path, source, fragments):
    population = JSONPopulation(write(tmp_path, "users.json", {"sources": [source]}), name="u")
    sim = Sim(line_topology([(0, 1, 1, 1)], {0: 1.0, 1: 1.0}), write_results=False)
    placement = JSONPlacement({"initialAllocation": [
        {"module_name": "Svc", "app": "consume", "id_resource": 1}]}, name="p")
    sim.deploy_app(consume_app(10), placement, population, MulticastAll())
    with pytest.raises(YAFSInputError) as excinfo:
        sim.run(10)
    assert_clear(excinfo, "users.json", *fragments)


def test_missing_file_is_reported(tmp_path):
    with pytest.raises(YAFSInputError) as excinfo:
        Topology().load(tmp_path / "absent.json")
    assert_clear(excinfo, "absent.json", "cannot read topology file")
