"""Rows of real YAFS3, reproduced row for row by the core's default (``yafs3``) engine.

``tests/golden/yafs3/<name>.csv`` and ``<name>_link.csv`` were written by YAFS3 itself
(branch YAFS3, Python 3.11) running the scenarios of ``yafs_examples/yafs3_scenarios.py``;
docs/core.md says how to recreate them. Each scenario is in the spirit of one of YAFS3's
tutorials or examples (see that module) and exercises the behaviour listed there: event
order at equal times, process ids, the ``buffer`` column, YAFS's re-routing after a failure,
the global random draws, module sources without request ids, ...
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest
from yafs_examples.yafs3_scenarios import SCENARIOS, run

GOLDEN = Path(__file__).resolve().parent / "golden" / "yafs3"


@pytest.fixture
def global_generators():
    """The scenarios seed Python's and numpy's global generators (as YAFS3's scripts do);
    put both back afterwards."""
    state, numpy_state = random.getstate(), np.random.get_state()
    yield
    random.setstate(state)
    np.random.set_state(numpy_state)


def rows(data: bytes) -> list[bytes]:
    # Compared line by line; the line ends are checked separately (git may rewrite them).
    return data.replace(b"\r\n", b"\n").split(b"\n")


@pytest.mark.filterwarnings("ignore:exponentialDistribution:FutureWarning")  # YAFS3's old name, used on purpose
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_rows_equal_yafs3s(tmp_path, name, global_generators):
    run(name, "yafs_safetail.yafs", str(tmp_path / name))
    for suffix in (".csv", "_link.csv"):
        expected = rows((GOLDEN / f"{name}{suffix}").read_bytes())
        written = (tmp_path / f"{name}{suffix}").read_bytes()
        actual = rows(written)
        assert len(expected) > 10, "golden file too small to mean anything"
        for index, (want, got) in enumerate(zip(expected, actual, strict=False)):
            assert got == want, f"{name}{suffix} line {index + 1}: {got!r} != YAFS3's {want!r}"
        assert len(actual) == len(expected), f"{name}{suffix}: {len(actual)} lines, YAFS3 wrote {len(expected)}"
        assert written.count(b"\r\n") == len(expected) - 1  # csv's line ends, as YAFS3 writes them


def test_the_golden_rows_show_what_the_scenarios_are_for():
    """Guards against a scenario silently losing the behaviour it is there for."""
    links = {name: [line.split(",") for line in (GOLDEN / f"{name}_link.csv").read_text().splitlines()[1:]]
             for name in SCENARIOS}
    events = {name: [line.split(",") for line in (GOLDEN / f"{name}.csv").read_text().splitlines()[1:]]
              for name in SCENARIOS}
    # Module source services (VRGame's Coordinator, Calculator): their messages carry id -1.
    assert any(row[0] == "-1" for row in links["vrgame"])
    # Copies queueing on one link: several hops in flight in the buffer column.
    assert max(int(row[9]) for row in links["json_modelling"]) >= 3
    # A zero-instruction module served on an integer clock: integer time_in, float time_out.
    zero = [row for row in events["json_modelling"] if row[3] == "C_0" and row[11].isdigit()]
    assert zero and all(row[12] == row[11] + ".0" for row in zero)
    # Re-routing by moving dst_int: some messages jump from one node to a non-adjacent one
    # (a hop starts where the previous one did not end).
    hops: dict[str, list[tuple[str, str]]] = {}
    for row in links["failures"]:
        hops.setdefault(row[0], []).append((row[2], row[3]))
    assert any(a[1] != b[0] for path in hops.values() for a, b in zip(path, path[1:], strict=False))
    # Users created during the run: process ids 0 (the monitor) and 1-3 (replicas) are
    # taken before the run, 4 by YAFS3's stop monitor, so the first new user is 5.
    assert min(int(row[5]) for row in events["user_movement"]) == 5
    # A replica stopped while waiting serves one more message; one whose node entry is gone
    # writes nothing: the moved services keep answering at both places for a while.
    moved = {(row[3], row[8]) for row in events["service_movement"]}
    assert len(moved) > 3
