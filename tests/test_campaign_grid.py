"""Campaign grids: checked whole before anything runs (one line per bad entry, exit 2, nothing
written), their paths resolved from the grid's folder or as the packaged defaults, and the
example grid of docs/campaigns.md valid and running from an empty folder."""

from __future__ import annotations

import json
import math
import re
import shutil
import tomllib
from pathlib import Path

import pytest
from in_process import run_in_process

from yafs_safetail.commands import campaign as campaign_command
from yafs_safetail.defaults import DATA_ROOT, DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.runs.campaign import STATE_FILE, recorded_run_id
from yafs_safetail.runs.grid import GridError, expand, load_grid
from yafs_safetail.settings.input_paths import packaged_default, resolve_input

REPOSITORY = Path(__file__).resolve().parents[1]
EXAMPLE_POLICY = REPOSITORY / "examples" / "custom_policy" / "nearest_free.py"
THREE_SERVERS = DATA_ROOT / "topologies" / "3servers.json"
VALID = {"base": 'steps_scale = 0.013\nfigures = false\n', "axes": "seed = [0]\n"}


def grid_file(folder: Path, base: str = "", axes: str = "", top: str = "") -> Path:
    """A TOML grid in ``folder``: the valid VALID entries plus ``base`` and ``axes`` lines."""
    grid = folder / "grid.toml"
    grid.write_text(f"{top}[base]\n{VALID['base']}{base}\n[axes]\n{VALID['axes']}{axes}\n")
    return grid


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """A grid's folder holding a few users' files: good and bad policies, a topology of the
    user's own (without a placement of its name), a file that is not JSON."""
    (tmp_path / "not_a_policy.py").write_text("class Plain:\n    pass\n")
    (tmp_path / "boom.py").write_text("raise RuntimeError('boom')\n")
    (tmp_path / "broken.json").write_text("{\n")
    (tmp_path / "down.csv").write_text("server,down_s,up_s\n4,0,60\n")  # a fifth server's outage
    (tmp_path / "walk.csv").write_text("time_s,x_m,y_m\n10,0,0\n5,1,0\n")  # back in time
    shutil.copy(THREE_SERVERS, tmp_path / "mine.json")
    return tmp_path


#: One bad entry each: (base lines, axes lines, the entry its line names, what the line says).
BAD_ENTRIES = {
    "unknown key": ("stepscale = 0.1\n", "", "base.stepscale", "did you mean 'steps_scale'?"),
    "a field the campaign sets": ("out_dir = 'x'\n", "", "base.out_dir", "set by the campaign"),
    "wrong type": ('learning_rate = "fast"\n', "", "base.learning_rate", "expected a positive number"),
    "a list expected": ("redundancy_levels = 2\n", "", "base.redundancy_levels", "expected a list"),
    "a path expected": ("topology = 5\n", "", "base.topology", "expected a path"),
    "the setting's check": ("", "use_case = [1, 4]\n", "axes.use_case[1]", "expected one of 1, 2, 3"),
    "a choice": ("", 'preset = ["papr"]\n', "axes.preset[0]", "expected one of paper"),
    "a range": ("", "failure_probability = [1.5]\n", "axes.failure_probability[0]", "a probability in [0, 1)"),
    "an axis that is no list": ("", "preset = 'paper'\n", "axes.preset", "expected a non-empty list"),
    "an empty axis": ("", "preset = []\n", "axes.preset", "expected a non-empty list"),
    "in base and axes": ("use_case = 1\n", "use_case = [1, 2]\n", "base.use_case", "not both"),
    "a missing file": ("", '"topology" = ["topologies/paper_7servers.json"]\n', "axes.topology[0]",
                       "no such file: neither"),
    "a missing absolute path": ('topology = "/nonexistent/t.json"\n', "", "base.topology",
                                "no such file: /nonexistent/t.json"),
    "a missing folder": ('traces_dir = "my_traces"\n', "", "base.traces_dir", "no such folder"),
    "a topology that is no JSON": ("", 'topology = ["broken.json"]\n', "axes.topology[0]", "invalid JSON"),
    "no placement for a user's topology": ("", 'topology = ["mine.json"]\n', "axes.topology[0]",
                                           "its placement, placements/mine.json"),
    "a topology with another's placement": ('placement = "placements/paper_5servers.json"\n',
                                            'topology = ["topologies/3servers.json"]\n',
                                            "axes.topology[0]", "is not an edge_server"),
    "a level above the servers": ('topology = "topologies/3servers.json"\n', "redundancy_levels = [[1, 4]]\n",
                                  "axes.redundancy_levels[0]", "x=4 is more than its 3 edge servers"),
    "an outage on no server": ('topology = "topologies/3servers.json"\n', 'down_intervals = ["down.csv"]\n',
                               "axes.down_intervals[0]", "4 is not one of the 3 servers"),
    "a route that goes back in time": ('topology = "topologies/campus_5servers.json"\nmobility = "route"\n',
                                       'route = ["walk.csv"]\n', "axes.route[0]",
                                       "walk.csv: point 2: time 5 s is before the previous point's (10 s)"),
    "a moving user among unplaced servers": ('mobility = "random-waypoint"\n', 'topology = ["topologies/3servers.json"]\n',
                                             "base.mobility", "needs every edge server's position"),
    "a level above the default topology's servers": ("", "redundancy_levels = [[1, 6]]\n",
                                                     "axes.redundancy_levels[0]", "x=6 is more than its 5"),
    "a method file that is missing": ("", 'methods = [["missing.py:X"]]\n', "axes.methods[0]", "no such file"),
    "a method that is no Policy": ("", 'methods = [["not_a_policy.py:Plain"]]\n', "axes.methods[0]",
                                   "'Plain' is not a Policy subclass"),
    "a method that fails to import": ('methods = ["boom.py:X"]\n', "", "base.methods", "RuntimeError: boom"),
    "an unknown world": ("", 'world = ["landed", "flat"]\n', "axes.world[1]", "expected one of landed"),
}


@pytest.mark.parametrize("case", sorted(BAD_ENTRIES))
def test_each_bad_entry_is_one_line_naming_the_grid_and_the_entry(case: str, folder: Path) -> None:
    base, axes, entry, problem = BAD_ENTRIES[case]
    grid = grid_file(folder, base, axes)
    with pytest.raises(GridError) as error:
        load_grid(grid)
    assert len(error.value.lines) == 1, error.value.lines
    line = error.value.lines[0]
    assert line.startswith(f"{grid}: {entry}") and problem in line and "\n" not in line, line
    assert "null" not in line, line  # a default is named in words, not as a missing value


def test_every_bad_entry_is_reported_at_once_and_nothing_is_written(folder: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    cases = ("unknown key", "wrong type", "the setting's check", "a missing file", "a method that is no Policy",
             "an unknown world")
    grid = grid_file(folder, "".join(BAD_ENTRIES[c][0] for c in cases), "".join(BAD_ENTRIES[c][1] for c in cases),
                     top="colour = 'blue'\n")
    monkeypatch.chdir(folder)
    before = sorted(p.name for p in folder.iterdir())
    done = run_in_process(campaign_command.main, "--grid", grid.name, "--out", "c_doc")
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == len(cases) + 1 and all(line.startswith("error: grid.toml: ") for line in lines), lines
    assert "colour: unknown entry" in lines[0]
    for case in cases:
        entry, problem = BAD_ENTRIES[case][2:]
        assert any(f"grid.toml: {entry} = " in line and problem in line for line in lines), case
    assert "Traceback" not in done.stderr and done.stdout == ""
    # Nothing ran and nothing was written: not even the campaign folder.
    assert sorted(p.name for p in folder.iterdir()) == before


def test_a_default_is_found_by_its_name_from_any_folder(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    assert resolve_input("topologies/3servers.json", empty) == THREE_SERVERS.resolve()
    spec, = expand({}, {"topology": ["topologies/3servers.json"]}, folder=empty)
    # The placement of the topology's name, as `run --topology` derives it.
    assert spec.settings["topology"] == str(THREE_SERVERS.resolve())
    assert spec.settings["placement"] == str((DATA_ROOT / "placements" / "3servers.json").resolve())
    # The default topology named by its name is the default run (the same id).
    named, = expand({}, {"topology": ["topologies/paper_5servers.json"]}, folder=empty)
    unnamed, = expand({}, {"seed": [0]}, folder=empty)
    assert named.run_id == unnamed.run_id
    assert named.settings["placement"] == str(DEFAULT_PLACEMENT.resolve())


def test_only_the_default_folders_fall_back_to_the_package(tmp_path: Path) -> None:
    # From a checkout DATA_ROOT holds the examples too, a wheel does not: found in neither.
    assert packaged_default("examples/custom_policy/nearest_free.py") is None
    assert packaged_default("topologies/none.json") is None
    assert packaged_default(DEFAULT_TOPOLOGY) is None  # absolute: taken as it is
    assert resolve_input("examples/custom_policy/nearest_free.py", tmp_path) == \
        tmp_path / "examples" / "custom_policy" / "nearest_free.py"


def test_a_users_file_beside_the_grid_wins_over_the_default_of_its_name(tmp_path: Path) -> None:
    (tmp_path / "topologies").mkdir()
    own = tmp_path / "topologies" / "3servers.json"
    own.write_text(THREE_SERVERS.read_text() + "\n")  # the same network, other bytes
    grid = grid_file(tmp_path, axes='topology = ["topologies/3servers.json"]\n')
    spec, = load_grid(grid)
    assert spec.settings["topology"] == str(own.resolve())
    # Its placement is still the packaged one of its name: none beside the grid.
    assert spec.settings["placement"] == str((DATA_ROOT / "placements" / "3servers.json").resolve())
    own.unlink()
    packaged, = load_grid(grid)
    assert packaged.settings["topology"] == str(THREE_SERVERS.resolve())
    assert packaged.run_id != spec.run_id  # the run id follows the file read


def test_paths_are_read_from_the_grids_folder_not_the_working_folder(folder: Path, tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    shutil.copy(EXAMPLE_POLICY, folder / "nearest_free.py")
    shutil.copy(DATA_ROOT / "placements" / "3servers.json", folder / "mine_placement.json")
    grid = grid_file(folder, 'topology = "mine.json"\nplacement = "mine_placement.json"\n',
                     'methods = [["nearest_free.py:NearestFree"], ["Near=./nearest_free.py:NearestFree"]]\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "mine.json").write_text("{\n")  # the working folder's file of that name is not read
    monkeypatch.chdir(elsewhere)
    first, second = load_grid(Path("..") / grid.name)  # the grid is in the parent folder
    assert first.settings["topology"] == str((folder / "mine.json").resolve())
    assert first.settings["placement"] == str((folder / "mine_placement.json").resolve())
    # A user's method: its file made absolute (workers may start anywhere), its NAME= kept.
    assert first.settings["methods"] == [f"{(folder / 'nearest_free.py').resolve()}:NearestFree"]
    assert second.settings["methods"] == [f"Near={(folder / 'nearest_free.py').resolve()}:NearestFree"]
    # Absolute paths are taken as they are.
    absolute = grid_file(folder, f'topology = "{DEFAULT_TOPOLOGY}"\n')
    assert load_grid(absolute)[0].settings["topology"] == str(DEFAULT_TOPOLOGY.resolve())


def docs_grid() -> str:
    """The TOML block under docs/campaigns.md's "The grid"."""
    text = (REPOSITORY / "docs" / "campaigns.md").read_text()
    section = text[text.index("## The grid"):]
    found = re.search(r"```toml\n(.*?)```", section, re.DOTALL)
    assert found is not None, "docs/campaigns.md: no ```toml block under 'The grid'"
    return found.group(1)


def test_the_docs_grid_is_valid_from_an_empty_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("docgrid.toml").write_text(docs_grid())
    data = tomllib.loads(docs_grid())
    specs = load_grid(Path("docgrid.toml"))
    sizes = [len(values) for values in data["axes"].values()]
    assert len(specs) == math.prod(sizes) and len({s.run_id for s in specs}) == len(specs)
    for spec in specs:  # every input file is a packaged default
        assert Path(spec.settings["topology"]).is_relative_to(DATA_ROOT.resolve())


def shrunk(grid: str) -> str:
    """The docs' grid at a test's budget: ``steps_scale`` 0.013 and no figures, each axis cut to
    its first value except the topologies (the paths under test). Written back as TOML: the
    grid's values (texts, numbers, booleans, lists of them) are spelt alike in JSON and TOML."""
    data = tomllib.loads(grid)
    data["base"].update(steps_scale=0.013, figures=False)
    axes = {key: values if key == "topology" else values[:1] for key, values in data["axes"].items()}
    lines = [f"name = {json.dumps(data['name'])}"] if "name" in data else []
    for table, entries in (("base", data["base"]), ("axes", axes)):
        lines += [f"[{table}]", *(f"{key} = {json.dumps(value)}" for key, value in entries.items())]
    return "\n".join(lines) + "\n"


def test_the_docs_grid_runs_from_an_empty_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("docgrid.toml").write_text(shrunk(docs_grid()))
    # One worker: one TensorFlow import for both runs (the suite runs tests side by side).
    done = run_in_process(campaign_command.main, "--grid", "docgrid.toml", "--out", "c_doc", "--quiet")
    assert done.returncode == 0, done.stderr
    state = json.loads((tmp_path / "c_doc" / STATE_FILE).read_text())
    topologies = tomllib.loads(docs_grid())["axes"]["topology"]
    assert len(state["runs"]) == len(topologies) >= 2
    assert [run["status"] for run in state["runs"]] == ["done"] * len(topologies)
    for run, topology in zip(state["runs"], topologies, strict=True):
        assert recorded_run_id(tmp_path / "c_doc" / run["name"]) == run["run_id"]
        recorded = json.loads((tmp_path / "c_doc" / run["name"] / "run.json").read_text())
        assert recorded["topology"] == topology  # the packaged default, by the name the grid gave
