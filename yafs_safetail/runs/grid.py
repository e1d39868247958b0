"""A campaign's grid: which runs it holds, what each one is called and what identifies it.

A grid is fixed settings (``base``) and axes (``axes``: a list of values per
:class:`~yafs_safetail.settings.experiment.ExperimentConfig` field that changes results); the campaign is every
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

The whole grid is checked before any run starts (:func:`expand`, through
``runs.grid_checks.check_grid``): each bad entry is one line of the :class:`GridError`. Paths
are resolved by ``settings.input_paths``: beside the grid file, else the packaged default of that
name; a topology without a placement gets ``placements/<topology file name>``, resolved the
same way, as ``run`` does.

A run's id is a short hash of everything its results depend on: every result-bearing field
(paths replaced by where they are and a digest of what they hold, so an edited topology or
trace file is a new run) and the code version (package version and git commit). Fields that
only say where and how a run goes (``out_dir``, ``workers``, ``progress``...; declared with
``changes_results=False`` in ``settings.experiment``) are not part of it.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import re
import subprocess
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yafs_safetail
from yafs_safetail.edge.calibration import WorldSettings, world_settings
from yafs_safetail.edge.scenario import REPOSITORY
from yafs_safetail.methods.registry import UserMethod
from yafs_safetail.runs.grid_checks import (  # (GridError and the field lists: re-exported)
    PATH_FIELDS,
    SETTABLE_FIELDS,
    GridError,
    check_grid,
    json_value,
    shown,
)
from yafs_safetail.settings.experiment import LATER_RESULT_FIELDS, RESULT_FIELDS, ExperimentConfig
from yafs_safetail.settings.experiment import RUNTIME_FIELDS as RUNTIME_FIELDS  # (re-exported)

#: Hex digits of a run id: 48 bits, so two configurations of one campaign never share one.
ID_LENGTH = 12


@dataclass(frozen=True)
class RunSpec:
    """One run of a campaign.

    Attributes:
        name: its folder under the campaign's folder (may hold ``/``).
        run_id: the hash of its identity (:func:`identity`).
        settings: the ExperimentConfig fields it sets, JSON values (paths absolute).
        kind: what executes it: ``"experiment"`` (``run_experiment``), ``"load_point"`` or
            ``"failure_point"`` (one point of a contention-world load or failure sweep,
            ``runs.sweep_points.run_sweep_point``).
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
        default = json_value(getattr(defaults, name))
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
        folder: where the grid's relative paths are read from (``settings.input_paths``; the grid
            file's folder); None: the working folder (a command's own options).

    Raises:
        GridError: one line per bad entry (every one found), or a name template that cannot be
            filled in or gives two runs one folder.
    """
    checked = check_grid(base, axes, source, Path.cwd() if folder is None else Path(folder))
    values, derived = checked.values, checked.derived_placements
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
            defaults = {f: json_value(getattr(ExperimentConfig(), f)) for f in SETTABLE_FIELDS}
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
    that name (``settings.input_paths``).

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
            problems.append(f"{path}: {key} = {shown(table)}: expected a table")
    if name is not None and not isinstance(name, str):
        problems.append(f"{path}: name = {shown(name)}: expected a text template")
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
    return run_id({name: json_value(getattr(config, name)) for name in RESULT_FIELDS})


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
