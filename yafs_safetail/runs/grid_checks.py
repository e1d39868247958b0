"""A campaign grid's entries, checked whole before any run starts.

Every entry of ``base`` and ``axes`` against its setting's check (``settings.experiment``), every input
file (resolved by ``settings.input_paths`` and read as the run reads it), every user's method
(loaded), and every topology with its placement, redundancy levels and scripted outages: each bad
entry is one line of the :class:`GridError`. ``runs.grid`` expands what passes into runs.
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from yafs_safetail.defaults import DATA_FILES, DATA_ROOT, DEFAULT_TOPOLOGY
from yafs_safetail.edge.calibration import WORLD_NAMES, WorldSettings, world_settings
from yafs_safetail.edge.failures import read_down_file
from yafs_safetail.edge.routes import read_route
from yafs_safetail.edge.scenario import load_placement, load_scenario, load_topology
from yafs_safetail.methods.registry import UserMethod
from yafs_safetail.methods.safetail.spaces import MAX_SERVERS
from yafs_safetail.settings.declare import setting_of
from yafs_safetail.settings.experiment import (
    GRID_RUNTIME_FIELDS,
    RESULT_FIELDS,
    RUNTIME_FIELDS,
    ExperimentConfig,
)
from yafs_safetail.settings.input_paths import resolve_input

#: RUNTIME_FIELDS (from settings.experiment) say where a run goes and how it shows itself, never what
#: it computes: the campaign sets them, and they are left out of the run id. A grid sets the
#: others, every field that may change the results (the run id hashes exactly these), and the
#: few runtime fields declared ``in_grid`` (which copies of the figures to draw).
SETTABLE_FIELDS = (*RESULT_FIELDS, *GRID_RUNTIME_FIELDS)
#: Settable fields holding a file or folder (identified by place and content).
PATH_FIELDS = tuple(f.name for f in fields(ExperimentConfig)
                    if f.name in SETTABLE_FIELDS and f.type in ("Path", "Path | None"))
#: Fields the campaign sets for every run itself (its folder, one process each...): a grid may not.
CAMPAIGN_FIELDS = tuple(name for name in RUNTIME_FIELDS if name not in GRID_RUNTIME_FIELDS)
#: Settings a grid writes as a list (ExperimentConfig holds a tuple).
LIST_FIELDS = ("redundancy_levels", "figure_formats", "methods")
#: The redundancy levels of a run that does not set them (Rand-x... for these x).
DEFAULT_LEVELS: tuple[int, ...] = ExperimentConfig().redundancy_levels

_FIELDS = {item.name: item for item in fields(ExperimentConfig)}


class GridError(ValueError):
    """A grid that cannot be expanded: one line per bad entry, each naming the grid file, the
    entry and the problem.

    Attributes:
        lines: every problem found, one line each (the campaign command prints them all; the
            message, for callers that print one line, joins them).
    """

    def __init__(self, *lines: str) -> None:
        self.lines: tuple[str, ...] = lines
        super().__init__(lines[0] if len(lines) == 1 else
                         f"{len(lines)} bad grid entries: " + "; ".join(lines))


class _BadEntry(Exception):
    """What is wrong with one grid entry (raised and caught inside this module)."""


def json_value(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple):
        return [json_value(v) for v in value]
    if isinstance(value, WorldSettings):
        return value.to_dict()
    if isinstance(value, UserMethod):
        return value.spec
    return value


def shown(value: Any) -> str:
    """A grid value as its line in an error shows it (JSON, close to how TOML spells it)."""
    try:
        return json.dumps(value)
    except (TypeError, ValueError):
        return repr(value)


def _unknown(name: str) -> str:
    """Why ``name`` is no setting a grid may set (a near miss suggested)."""
    if name in CAMPAIGN_FIELDS:
        return "set by the campaign for every run, not by a grid (--out and the engine options say where runs go)"
    close = difflib.get_close_matches(name, (*SETTABLE_FIELDS, *CAMPAIGN_FIELDS), n=1)
    if close and close[0] in CAMPAIGN_FIELDS:
        return f"not a run setting; did you mean {close[0]!r}? The campaign sets that one, not a grid"
    if close:
        return f"not a run setting; did you mean {close[0]!r}?"
    return f"not a run setting (valid: {', '.join(SETTABLE_FIELDS)})"


def _input_file(name: str, value: Any, folder: Path) -> str:
    """A path entry resolved (``settings.input_paths``), checked to exist and, for a topology or a
    placement, read as the run reads it."""
    if not isinstance(value, str) or not value:
        raise _BadEntry("expected a path")
    path = resolve_input(value, folder)
    is_folder = name == "traces_dir"
    if not (path.is_dir() if is_folder else path.is_file()):
        raise _BadEntry(f"no such {'folder' if is_folder else 'file'}: {_missing(value, path)}")
    try:
        if name == "topology":
            load_topology(path)
        elif name == "placement":
            load_placement(path)
    except ValueError as error:  # ScenarioError: the file, the field and the problem
        raise _BadEntry(" ".join(str(error).split())) from None
    return str(path)


def _missing(value: str, path: Path) -> str:
    """Where a path that exists nowhere was looked for (and the defaults it could have meant)."""
    given = Path(value).expanduser()
    if given.is_absolute():
        return str(path)
    if given.parts[0] not in DATA_FILES:
        return f"{path} (a relative path is read from the grid's folder)"
    first = given.parts[0]
    shipped = sorted(p.name for p in (DATA_ROOT / first).glob("*.json"))
    listed = f"; the packaged {first}/ holds {', '.join(shipped)}" if shipped else ""
    return f"neither {path} nor a packaged default{listed}"


def _method_spec(spec: Any, folder: Path) -> str:
    """A user's method spec with its file resolved from the grid's folder, loaded (a class that
    cannot load is reported now, not by each run)."""
    if not isinstance(spec, str):
        raise _BadEntry(f"expected [NAME=]FILE.py:CLASS or module:CLASS texts, got {shown(spec)}")
    name, sep, target = spec.partition("=")
    if not sep or ":" in name or "/" in name:  # no NAME= prefix (as UserMethod reads it)
        name, sep, target = "", "", spec
    source, colon, class_name = target.rpartition(":")
    if source.endswith(".py") or "/" in source or "\\" in source:
        # Absolute, so that every worker (and every Ray node's copy of the checkout) reads it.
        target = f"{resolve_input(source, folder)}{colon}{class_name}"
    resolved = f"{name}{sep}{target}"
    try:
        UserMethod(resolved)
    except ValueError as error:  # PolicyError: "--method SPEC: what is wrong"
        problem = " ".join(str(error).split())
        raise _BadEntry(problem.removeprefix(f"--method {resolved}: ")) from None
    return resolved


def _world(value: Any) -> None:
    """Check a ``world`` entry: a world's name or a table of its settings."""
    if isinstance(value, str):
        if value not in WORLD_NAMES:
            raise _BadEntry(f"expected one of {', '.join(WORLD_NAMES)}, or a table of a world's settings")
        try:
            world_settings(value)
        except ValueError as error:  # the calibration file cannot be read
            raise _BadEntry(" ".join(str(error).split())) from None
    elif isinstance(value, dict):
        try:
            WorldSettings(**value)
        except (TypeError, ValueError) as error:
            raise _BadEntry(f"not a world's settings: {error}") from None
    else:
        raise _BadEntry(f"expected one of {', '.join(WORLD_NAMES)}, or a table of a world's settings")


def _grid_value(name: str, value: Any, folder: Path) -> Any:
    """One grid entry as the JSON value the run is identified by, checked as the run would
    check it (its setting's check, its files, its methods).

    Args:
        name: the setting.
        value: its value as the grid file holds it.
        folder: the grid file's folder, from which its relative paths are read.

    Raises:
        _BadEntry: what is wrong with it.
    """
    if name not in SETTABLE_FIELDS:
        raise _BadEntry(_unknown(name))
    about = setting_of(_FIELDS[name])
    if value is None:
        if about.optional:
            return None
        raise _BadEntry("expected a value; this setting cannot be null")
    if name in PATH_FIELDS:
        return _input_file(name, value, folder)
    if name in LIST_FIELDS:
        if not isinstance(value, list | tuple):
            raise _BadEntry("expected a list")
        value = tuple(value)
        if name == "methods":
            return [_method_spec(spec, folder) for spec in value]
    if name == "world":
        _world(value)
    elif about.check is not None and not about.check.accepts(value):
        raise _BadEntry(f"expected {about.check.what}")
    return json_value(value)


@dataclass(frozen=True)
class GridValue:
    """One value a setting takes in a grid: where it is written, as written, as checked."""

    where: str
    written: Any
    value: Any

    @property
    def named(self) -> str:
        """How an error names it: ``axes.topology[1] = "t.json"``, or a default by its words."""
        return self.where if self.written is None else f"{self.where} = {shown(self.written)}"


def _entries(base: Mapping[str, Any], axes: Mapping[str, Any], source: str,
             folder: Path) -> tuple[dict[str, list[GridValue]], list[str]]:
    """Every value of every entry, checked: per setting its values, and one line per bad entry."""
    values: dict[str, list[GridValue]] = {}
    problems: list[str] = []

    def check(key: str, where: str, written: Any) -> None:
        try:
            value = _grid_value(key, written, folder)
        except _BadEntry as bad:
            problems.append(f"{source}: {where} = {shown(written)}: {bad}")
        else:
            values.setdefault(key, []).append(GridValue(where, written, value))

    for key, written in base.items():
        if key in axes:  # which one would win is a guess: say so rather than pick
            problems.append(f"{source}: base.{key} = {shown(written)}: also an axis; set it in [base] "
                            "or in [axes], not both")
        elif key not in SETTABLE_FIELDS:
            problems.append(f"{source}: base.{key} = {shown(written)}: {_unknown(key)}")
        else:
            check(key, f"base.{key}", written)
    for key, listed in axes.items():
        if key not in SETTABLE_FIELDS:
            problems.append(f"{source}: axes.{key} = {shown(listed)}: {_unknown(key)}")
        elif not isinstance(listed, list | tuple) or not listed:
            problems.append(f"{source}: axes.{key} = {shown(listed)}: expected a non-empty list of values")
        else:
            for index, written in enumerate(listed):
                check(key, f"axes.{key}[{index}]", written)
    return values, problems


def _placements(values: Mapping[str, list[GridValue]], named: set[str], source: str,
                folder: Path) -> tuple[dict[str, str], list[str]]:
    """The placement of each (good) topology when the grid names no placement (``named``: the
    settings it sets), as ``run`` derives it: ``placements/<topology file name>``, resolved as
    any grid path."""
    if "placement" in named:
        return {}, []
    derived: dict[str, str] = {}
    problems: list[str] = []
    for topology in values.get("topology", []):
        name = f"placements/{Path(topology.value).name}"
        path = resolve_input(name, folder)
        if path.is_file():
            derived[topology.value] = str(path)
        else:
            problems.append(f"{source}: {topology.where} = {shown(topology.written)}: its placement, {name} "
                            "(no placement set: placements/<topology file name>), is "
                            f"{_missing(name, path)}; set placement in [base]")
    return derived, problems


def _scenario_problems(values: Mapping[str, list[GridValue]], named: set[str], derived: Mapping[str, str],
                       source: str) -> list[str]:
    """Each topology with each placement and each set of redundancy levels it runs with, checked
    as a run checks them (servers placed, 1 to MAX_SERVERS of them, every level x within them,
    every scripted outage on one of them).
    Only good entries are paired (a bad one has its own line); ``named``: the settings the grid
    sets."""
    if not named & {"topology", "placement", "redundancy_levels", "down_intervals", "route", "mobility"}:
        return []  # the defaults, which every run of the project checks
    default_topology = GridValue("the default topology", None, str(DEFAULT_TOPOLOGY))
    topologies = values.get("topology", []) if "topology" in named else [default_topology]
    placements = values.get("placement", []) if "placement" in named else None
    levels = values.get("redundancy_levels", []) if "redundancy_levels" in named else [
        GridValue("redundancy_levels (default)", None, list(DEFAULT_LEVELS))]
    problems: list[str] = []
    for topology in topologies:
        if placements is not None:
            paired = placements
        elif topology.value in derived:
            paired = [GridValue(f"its placement {derived[topology.value]}", None, derived[topology.value])]
        elif "topology" not in named:  # the default topology, with the default placement
            paired = [GridValue("the default placement", None, str(ExperimentConfig().placement))]
        else:  # its placement is missing: a line of its own already
            continue
        for placement in paired:
            try:
                scenario = load_scenario(topology.value, placement.value)
            except ValueError as error:
                problems.append(f"{source}: {topology.named} with {placement.where}: "
                                f"{' '.join(str(error).split())}")
                continue
            n_servers = scenario.n_servers
            if n_servers > MAX_SERVERS:
                problems.append(f"{source}: {topology.named}: {n_servers} edge servers; SafeTail "
                                f"supports 1 to {MAX_SERVERS}")
                continue
            for level in levels:
                above = [x for x in level.value if x > n_servers]
                if above:
                    problems.append(f"{source}: {level.where} = {shown(level.value)} with "
                                    f"{topology.named}: x={above[0]} is more than its {n_servers} edge servers")
            for outages in values.get("down_intervals", []):
                if outages.value is None:
                    continue
                try:
                    read_down_file(Path(outages.value), n_servers)
                except ValueError as error:  # FailureFileError: the file, the row, the field
                    problems.append(f"{source}: {outages.named} with {topology.named}: "
                                    f"{' '.join(str(error).split())}")
            for mobility in values.get("mobility", []):
                if mobility.value != "off" and not scenario.topology.server_positions_m:
                    problems.append(f"{source}: {mobility.named} with {topology.named}: a user who moves needs "
                                    "every edge server's position (x, y in metres, or lat, lon)")
            for route in values.get("route", []):
                if route.value is None:
                    continue
                try:  # degrees need the topology's origin: read with each topology
                    read_route(Path(route.value), scenario.topology.origin)
                except ValueError as error:  # RouteError: the file, the point, what is wrong
                    problems.append(f"{source}: {route.named} with {topology.named}: {error}")
    return list(dict.fromkeys(problems))  # a pair met twice is one line


@dataclass(frozen=True)
class CheckedGrid:
    """A grid whose every entry passed: each setting's values, and the placement ``run`` derives
    for each topology when the grid names none (``{}`` when it names one)."""

    values: Mapping[str, list[GridValue]]
    derived_placements: Mapping[str, str]


def check_grid(base: Mapping[str, Any], axes: Mapping[str, Any], source: str, folder: Path) -> CheckedGrid:
    """Check a grid whole (see the module's docstring).

    Raises:
        GridError: one line per bad entry, every one found.
    """
    values, problems = _entries(base, axes, source, folder)
    named = {*base, *axes}
    derived, missing = _placements(values, named, source, folder)
    problems += missing
    problems += _scenario_problems(values, named, derived, source)  # each good topology's runs
    if problems:
        raise GridError(*problems)
    return CheckedGrid(values, derived)
