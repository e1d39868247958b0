"""A campaign's grid: which runs it holds, what each one is called and what identifies it.

A grid is fixed settings (``base``) and axes (``axes``: a list of values per
:class:`~yafs_safetail.runs.config.ExperimentConfig` field that changes results); the campaign is every
combination, the first axis outermost. Written by hand as TOML, YAML or JSON::

    name = "uc{use_case}-{preset}-seed{seed}-{id}"    # optional; the default names each axis
    [base]
    steps_scale = 0.1
    figures = false
    [axes]
    use_case = [1, 2]
    preset = ["paper", "tuned"]
    seed = [0, 1, 2, 3, 4]
    topology = ["topologies/paper_5servers.json", "topologies/3servers.json"]

The whole grid is checked before any run starts (:func:`expand`): every entry of ``base`` and
``axes`` against its setting's check, every input file (read as the run reads it), every user's
method (loaded), and every topology with its placement; each bad entry is one line of the
:class:`GridError`. Paths are resolved by ``runs.input_paths``: beside the grid file, else the
packaged default of that name; a topology without a placement gets
``placements/<topology file name>``, resolved the same way, as ``run`` does.

A run's id is a short hash of everything its results depend on: every result-bearing field
(paths replaced by where they are and a digest of what they hold, so an edited topology or
trace file is a new run) and the code version (package version and git commit). Fields that
only say where and how a run goes (``out_dir``, ``workers``, ``progress``...; declared with
``changes_results=False`` in ``runs.config``) are not part of it.
"""

from __future__ import annotations

import difflib
import functools
import hashlib
import itertools
import json
import re
import subprocess
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import yafs_safetail
from yafs_safetail.defaults import DATA_FILES, DATA_ROOT, DEFAULT_TOPOLOGY
from yafs_safetail.edge.calibration import WORLD_NAMES, WorldSettings, world_settings
from yafs_safetail.edge.failures import read_down_file
from yafs_safetail.edge.scenario import REPOSITORY, load_placement, load_scenario, load_topology
from yafs_safetail.methods.registry import UserMethod
from yafs_safetail.methods.safetail.spaces import MAX_SERVERS
from yafs_safetail.runs.config import (
    GRID_RUNTIME_FIELDS,
    LATER_RESULT_FIELDS,
    RESULT_FIELDS,
    ExperimentConfig,
    setting_of,
)
from yafs_safetail.runs.config import RUNTIME_FIELDS as RUNTIME_FIELDS  # (re-exported)
from yafs_safetail.runs.input_paths import resolve_input

#: Hex digits of a run id: 48 bits, so two configurations of one campaign never share one.
ID_LENGTH = 12

#: RUNTIME_FIELDS (from runs.config) say where a run goes and how it shows itself, never what
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


@dataclass(frozen=True)
class RunSpec:
    """One run of a campaign.

    Attributes:
        name: its folder under the campaign's folder (may hold ``/``).
        run_id: the hash of its identity (:func:`identity`).
        settings: the ExperimentConfig fields it sets, JSON values (paths absolute).
        kind: what executes it: ``"experiment"`` (``run_experiment``), ``"load_point"`` or
            ``"failure_point"`` (one point of a contention-world load or failure sweep,
            ``contention.sweep.run_sweep_point``).
    """

    name: str
    run_id: str
    settings: Mapping[str, Any]
    kind: str = "experiment"


@functools.cache
def code_version() -> str:
    """The package version and, in a git checkout, the commit: ``0.1.0+git.<sha>``."""
    try:
        commit = subprocess.run(["git", "-C", str(REPOSITORY), "rev-parse", "HEAD"],
                                capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return yafs_safetail.__version__
    return f"{yafs_safetail.__version__}+git.{commit}"


def _digest(path: Path) -> str:
    """SHA-256 of a file, or of every file under a folder (names and contents)."""
    sha = hashlib.sha256()
    if path.is_dir():
        for item in sorted(p for p in path.rglob("*") if p.is_file()):
            relative = item.relative_to(path)
            if any(part.startswith(".") or part == "__pycache__" for part in relative.parts):
                continue
            sha.update(str(relative).encode() + b"\0" + item.read_bytes() + b"\0")
    elif path.is_file():
        sha.update(path.read_bytes())
    else:
        return "missing"  # the run itself reports it; the id only has to be stable
    return sha.hexdigest()


def _where(path: Path) -> str:
    # Inside the project the place is recorded relative to it, so that the same campaign in
    # another checkout has the same ids.
    resolved = path.resolve()
    return str(resolved.relative_to(REPOSITORY)) if resolved.is_relative_to(REPOSITORY) else str(resolved)


def file_identity(path: Path) -> dict[str, str]:
    """A file's place and content in a run's identity (an edited file is a new run)."""
    return {"path": _where(path), "sha256": _digest(path)}


def _method_identity(spec: str) -> dict[str, str]:
    target = spec.partition("=")[2] if "=" in spec.split(":")[0] else spec
    source = Path(target.rpartition(":")[0])
    return {"spec": spec, "sha256": _digest(source) if source.suffix == ".py" else "module"}


def identity(settings: Mapping[str, Any]) -> dict[str, Any]:
    """Everything a run's results depend on, as canonical JSON values."""
    defaults = ExperimentConfig()
    full: dict[str, Any] = {}
    for name in RESULT_FIELDS:
        default = _json_value(getattr(defaults, name))
        value = settings.get(name, default)
        if name in LATER_RESULT_FIELDS and value == default:
            continue  # a field added later is hashed only when set: earlier ids stay
        if name in PATH_FIELDS and value is not None:
            value = file_identity(Path(value))
        elif name == "methods":
            value = [_method_identity(spec) for spec in value]
        full[name] = value
    full["code_version"] = code_version()
    return full


def run_id(settings: Mapping[str, Any]) -> str:
    """The short hash of :func:`identity` (sorted-key JSON)."""
    canonical = json.dumps(identity(settings), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:ID_LENGTH]


def _json_value(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple):
        return [_json_value(v) for v in value]
    if isinstance(value, WorldSettings):
        return value.to_dict()
    if isinstance(value, UserMethod):
        return value.spec
    return value


def _shown(value: Any) -> str:
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
    """A path entry resolved (``runs.input_paths``), checked to exist and, for a topology or a
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
        raise _BadEntry(f"expected [NAME=]FILE.py:CLASS or module:CLASS texts, got {_shown(spec)}")
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
    return _json_value(value)


@dataclass(frozen=True)
class _Value:
    """One value a setting takes in a grid: where it is written, as written, as checked."""

    where: str
    written: Any
    value: Any

    @property
    def named(self) -> str:
        """How an error names it: ``axes.topology[1] = "t.json"``, or a default by its words."""
        return self.where if self.written is None else f"{self.where} = {_shown(self.written)}"


def _label(name: str, value: Any) -> str:
    """How one axis value reads in a folder name."""
    if name in ("use_case", "seed"):
        return f"{'uc' if name == 'use_case' else 'seed'}{value}"
    if name == "preset":
        return str(value)
    if name in PATH_FIELDS and value is not None:
        return Path(value).stem
    text = json.dumps(value) if not isinstance(value, str) else value
    return f"{name}-{text}"


def _clean(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._=+/-]+", "_", text).strip("_") or "run"


def _entries(base: Mapping[str, Any], axes: Mapping[str, Any], source: str,
             folder: Path) -> tuple[dict[str, list[_Value]], list[str]]:
    """Every value of every entry, checked: per setting its values, and one line per bad entry."""
    values: dict[str, list[_Value]] = {}
    problems: list[str] = []

    def check(key: str, where: str, written: Any) -> None:
        try:
            value = _grid_value(key, written, folder)
        except _BadEntry as bad:
            problems.append(f"{source}: {where} = {_shown(written)}: {bad}")
        else:
            values.setdefault(key, []).append(_Value(where, written, value))

    for key, written in base.items():
        if key in axes:  # which one would win is a guess: say so rather than pick
            problems.append(f"{source}: base.{key} = {_shown(written)}: also an axis; set it in [base] "
                            "or in [axes], not both")
        elif key not in SETTABLE_FIELDS:
            problems.append(f"{source}: base.{key} = {_shown(written)}: {_unknown(key)}")
        else:
            check(key, f"base.{key}", written)
    for key, listed in axes.items():
        if key not in SETTABLE_FIELDS:
            problems.append(f"{source}: axes.{key} = {_shown(listed)}: {_unknown(key)}")
        elif not isinstance(listed, list | tuple) or not listed:
            problems.append(f"{source}: axes.{key} = {_shown(listed)}: expected a non-empty list of values")
        else:
            for index, written in enumerate(listed):
                check(key, f"axes.{key}[{index}]", written)
    return values, problems


def _placements(values: Mapping[str, list[_Value]], named: set[str], source: str,
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
            problems.append(f"{source}: {topology.where} = {_shown(topology.written)}: its placement, {name} "
                            "(no placement set: placements/<topology file name>), is "
                            f"{_missing(name, path)}; set placement in [base]")
    return derived, problems


def _scenario_problems(values: Mapping[str, list[_Value]], named: set[str], derived: Mapping[str, str],
                       source: str) -> list[str]:
    """Each topology with each placement and each set of redundancy levels it runs with, checked
    as a run checks them (servers placed, 1 to MAX_SERVERS of them, every level x within them,
    every scripted outage on one of them).
    Only good entries are paired (a bad one has its own line); ``named``: the settings the grid
    sets."""
    if not named & {"topology", "placement", "redundancy_levels", "down_intervals"}:
        return []  # the defaults, which every run of the project checks
    default_topology = _Value("the default topology", None, str(DEFAULT_TOPOLOGY))
    topologies = values.get("topology", []) if "topology" in named else [default_topology]
    placements = values.get("placement", []) if "placement" in named else None
    levels = values.get("redundancy_levels", []) if "redundancy_levels" in named else [
        _Value("redundancy_levels (default)", None, list(DEFAULT_LEVELS))]
    problems: list[str] = []
    for topology in topologies:
        if placements is not None:
            paired = placements
        elif topology.value in derived:
            paired = [_Value(f"its placement {derived[topology.value]}", None, derived[topology.value])]
        elif "topology" not in named:  # the default topology, with the default placement
            paired = [_Value("the default placement", None, str(ExperimentConfig().placement))]
        else:  # its placement is missing: a line of its own already
            continue
        for placement in paired:
            try:
                n_servers = load_scenario(topology.value, placement.value).n_servers
            except ValueError as error:
                problems.append(f"{source}: {topology.named} with {placement.where}: "
                                f"{' '.join(str(error).split())}")
                continue
            if n_servers > MAX_SERVERS:
                problems.append(f"{source}: {topology.named}: {n_servers} edge servers; SafeTail "
                                f"supports 1 to {MAX_SERVERS}")
                continue
            for level in levels:
                above = [x for x in level.value if x > n_servers]
                if above:
                    problems.append(f"{source}: {level.where} = {_shown(level.value)} with "
                                    f"{topology.named}: x={above[0]} is more than its {n_servers} edge servers")
            for outages in values.get("down_intervals", []):
                if outages.value is None:
                    continue
                try:
                    read_down_file(Path(outages.value), n_servers)
                except ValueError as error:  # FailureFileError: the file, the row, the field
                    problems.append(f"{source}: {outages.named} with {topology.named}: "
                                    f"{' '.join(str(error).split())}")
    return list(dict.fromkeys(problems))  # a pair met twice is one line


def expand(base: Mapping[str, Any], axes: Mapping[str, Sequence[Any]], name: str | None = None,
           source: str = "grid", folder: Path | None = None) -> list[RunSpec]:
    """Every combination of ``axes`` over ``base`` (first axis outermost) as run specs, after
    checking the grid whole.

    Args:
        base: settings shared by every run.
        axes: per setting, the values it takes.
        name: a folder-name template over the settings and ``{id}`` (``str.format``); None:
            the axes' values and the id, e.g. ``uc1-paper-seed0-<id>``.
        source: what to name in errors (the grid file).
        folder: where the grid's relative paths are read from (``runs.input_paths``; the grid
            file's folder); None: the working folder (a command's own options).

    Raises:
        GridError: one line per bad entry (every one found), or a name template that cannot be
            filled in or gives two runs one folder.
    """
    folder = Path.cwd() if folder is None else Path(folder)
    values, problems = _entries(base, axes, source, folder)
    named = {*base, *axes}
    derived, missing = _placements(values, named, source, folder)
    problems += missing
    problems += _scenario_problems(values, named, derived, source)  # each good topology's runs
    if problems:
        raise GridError(*problems)
    fixed = {key: values[key][0].value for key in base}
    keys = list(axes)
    specs: list[RunSpec] = []
    seen: dict[str, str] = {}
    for combination in itertools.product(*(values[key] for key in keys)):
        settings = dict(fixed)
        settings.update({key: item.value for key, item in zip(keys, combination, strict=True)})
        if derived:
            settings["placement"] = derived[settings["topology"]]
        identifier = run_id(settings)
        if name is None:
            labels = [_label(key, item.written) for key, item in zip(keys, combination, strict=True)]
            folder_name = "-".join([*labels, identifier])
        else:
            defaults = {f: _json_value(getattr(ExperimentConfig(), f)) for f in SETTABLE_FIELDS}
            try:
                folder_name = name.format(**{**defaults, **settings, "id": identifier})
            except (KeyError, IndexError, ValueError, AttributeError) as error:
                raise GridError(f"{source}: name {name!r}: cannot fill it in ({error})") from None
        folder_name = _clean(folder_name)
        if folder_name.startswith("/") or ".." in folder_name.split("/"):
            raise GridError(f"{source}: name {name!r} gives {folder_name!r}, which leaves the campaign folder")
        if folder_name in seen and seen[folder_name] != identifier:
            raise GridError(f"{source}: name {name!r} gives two different runs the folder {folder_name!r}; "
                            "add the setting that tells them apart, or {id}")
        if folder_name not in seen:
            seen[folder_name] = identifier
            specs.append(RunSpec(name=folder_name, run_id=identifier, settings=settings))
    return specs


def load_grid(path: Path) -> list[RunSpec]:
    """The runs of a grid file (``.toml``, ``.yaml``/``.yml`` or ``.json``), checked whole.

    Its relative paths are read from the grid file's folder, else are the packaged defaults of
    that name (``runs.input_paths``).

    Raises:
        GridError: a file that cannot be read or parsed, or one line per bad entry.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise GridError(f"{path}: cannot read it: {error.strerror}") from None
    try:
        if path.suffix == ".toml":
            data = tomllib.loads(text)
        elif path.suffix in (".yaml", ".yml"):
            try:
                import yaml
            except ImportError:
                raise GridError(f"{path}: YAML grids need PyYAML (pip install pyyaml); "
                                "or write the grid as TOML") from None
            data = yaml.safe_load(text)
        elif path.suffix == ".json":
            data = json.loads(text)
        else:
            raise GridError(f"{path}: expected a .toml, .yaml or .json grid")
    except GridError:
        raise
    except Exception as error:  # each parser has its own error class; all mean "not parsable"
        raise GridError(f"{path}: not valid {path.suffix[1:].upper()}: {' '.join(str(error).split())}") from None
    if not isinstance(data, dict):
        raise GridError(f"{path}: expected a table with [base] and [axes]")
    problems = [f"{path}: {key}: unknown entry; a grid has name, [base] and [axes]"
                for key in sorted(set(data) - {"base", "axes", "name"})]
    base, axes, name = data.get("base", {}), data.get("axes", {}), data.get("name")
    for key, table in (("base", base), ("axes", axes)):
        if not isinstance(table, dict):
            problems.append(f"{path}: {key} = {_shown(table)}: expected a table")
    if name is not None and not isinstance(name, str):
        problems.append(f"{path}: name = {_shown(name)}: expected a text template")
    try:
        specs = expand(base if isinstance(base, dict) else {}, axes if isinstance(axes, dict) else {},
                       name if isinstance(name, str) else None, source=str(path), folder=path.parent)
    except GridError as error:
        problems += error.lines
    if problems:
        raise GridError(*problems)
    return specs


def config_run_id(config: ExperimentConfig) -> str:
    """The run id of an ExperimentConfig's settings (what its results depend on)."""
    return run_id({name: _json_value(getattr(config, name)) for name in RESULT_FIELDS})


def make_config(spec: RunSpec, out_dir: Path, command: str = "", overwrite: bool = False) -> ExperimentConfig:
    """The ExperimentConfig of one run (one process for it: the campaign runs runs in parallel).

    Raises:
        ValueError: a setting of the wrong kind (a user's policy that cannot be loaded...).
    """
    values: dict[str, Any] = {}
    for key, value in spec.settings.items():
        if key in PATH_FIELDS and value is not None:
            value = Path(value)
        elif key in ("redundancy_levels", "figure_formats"):
            value = tuple(value)
        elif key == "methods":
            value = tuple(UserMethod(str(item)) for item in value)
        elif key == "world" and value is not None:
            value = world_settings(value) if isinstance(value, str) else WorldSettings(**value)
        values[key] = value
    try:
        return ExperimentConfig(**values, out_dir=out_dir, command=command, overwrite=overwrite,
                                workers=1, progress=False, run_id=spec.run_id)
    except TypeError as error:
        raise GridError(f"run {spec.name}: {error}") from None
