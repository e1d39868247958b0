"""Fuzzed user inputs: every topology, placement, trace CSV and arrivals file either loads or
stops with the project's one-line ValueError, never another exception."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from yafs_safetail.contention.world import read_arrivals
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY, load_placement
from yafs_safetail.edge.topology_io import load_topology
from yafs_safetail.edge.traces import (
    DEFAULT_TRACE_DIR,
    load_bandwidth,
    load_compute,
    load_load_trace,
    load_propagation,
)

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 12) | st.floats(allow_nan=True) | st.text(max_size=4),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12,
)


def _one_line_or_loads(load, source) -> None:
    try:
        load(source)
    except ValueError as error:
        assert "\n" not in str(error) and str(error)


def _mutations(document: dict) -> st.SearchStrategy:
    """The shipped document with one entry's field replaced, removed or added."""
    def mutate(args):
        key, index, field, value, action = args
        data = json.loads(json.dumps(document))
        items = data.get(key) or [{}]
        entry = items[index % len(items)]
        if isinstance(entry, dict):
            fields = sorted(entry) or ["x"]
            name = fields[field % len(fields)]
            if action == "remove":
                entry.pop(name, None)
            else:
                entry[name if action == "replace" else f"{name}_"] = value
        return data
    keys = st.sampled_from(sorted(document))
    return st.tuples(keys, st.integers(0, 20), st.integers(0, 20), json_values,
                     st.sampled_from(["replace", "remove", "add"])).map(mutate)


@FUZZ
@given(_mutations(json.loads(DEFAULT_TOPOLOGY.read_text())))
def test_topology_files(data):
    _one_line_or_loads(load_topology, data)


@FUZZ
@given(_mutations(json.loads(DEFAULT_PLACEMENT.read_text())))
def test_placement_files(data):
    _one_line_or_loads(load_placement, data)


@FUZZ
@given(json_values)
def test_any_json_as_topology(value):
    _one_line_or_loads(load_topology, {"entity": value, "link": value} if isinstance(value, list) else {"x": value})


def _csv_mutations(path: Path, rows: int = 12) -> st.SearchStrategy:
    lines = path.read_text().splitlines()[:rows]

    def mutate(args):
        line, column, value, action = args
        out = [row.split(",") for row in lines]
        row = out[line % len(out)]
        index = column % len(row)
        if action == "replace":
            row[index] = value
        elif action == "drop":
            del row[index]
        else:
            out = out[: line % len(out)]
        return "\n".join(",".join(r) for r in out) + "\n"
    cell = st.sampled_from(["", "nan", "-1", "1e400", "x", "0", "3.5", " ", "1,2"])
    return st.tuples(st.integers(0, rows), st.integers(0, 20), cell,
                     st.sampled_from(["replace", "drop", "truncate"])).map(mutate)


@pytest.mark.parametrize(("name", "loader"), [
    ("load.csv", load_load_trace), ("bandwidth.csv", load_bandwidth),
    ("propagation.csv", load_propagation), ("compute_uc1.csv", lambda p: load_compute(p, 1)),
])
def test_trace_csvs(tmp_path_factory, name, loader):
    folder = tmp_path_factory.mktemp("fuzz")

    @FUZZ
    @given(_csv_mutations(DEFAULT_TRACE_DIR / name))
    def check(text):
        path = folder / name
        path.write_text(text)
        _one_line_or_loads(loader, path)

    check()


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(["0.5", "1", "-2", "nan", "x", "", "1e999"]),
                          st.sampled_from(["0", "1", "5", "-1", "a", ""])), max_size=5),
       st.sampled_from(["time_s,user", "time,user", ""]))
def test_arrivals_csvs(tmp_path_factory, rows, header):
    path = tmp_path_factory.mktemp("arrivals") / "arrivals.csv"
    path.write_text("\n".join([header, *(",".join(row) for row in rows)]) + "\n")
    _one_line_or_loads(lambda p: read_arrivals(p, users=3), path)
