"""The package's floors (docs/architecture.md, "Layers"): who may import whom.

Every module under yafs_safetail/ is parsed with ``ast``; every import counts, at the top, inside
a function (a lazy import is still a dependency) or under ``if TYPE_CHECKING:``.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "yafs_safetail"

#: The floors, lowest first (docs/architecture.md, "Layers"): a module may import its own package
#: and any package or root module on a lower floor, never one on its own floor or above.
FLOORS: tuple[tuple[str, ...], ...] = (
    ("defaults", "numerics", "logs", "stopping"),  # root modules on the standard library alone
    ("versions", "settings", "yafs"),  # every setting declared once; the YAFS core
    ("edge",),  # the paper's edge world
    ("record",),  # the one request row
    ("methods",),  # what decides where copies go
    ("observation_space",),  # ω^t as a Gymnasium space
    ("worlds",),  # the paper's world built from a configuration
    ("sim", "contention", "results"),  # the two engines; the results folder and its reports
    ("runs",),  # runs and campaigns (the sweeps too)
    ("cli",),
    ("commands",),
    ("api",),
)
FLOOR_OF = {name: level for level, names in enumerate(FLOORS) for name in names}
#: Below the commands: none of these imports ``cli`` (only ``commands`` and ``cli`` itself do).
NOT_CLI = tuple(name for name in FLOOR_OF if FLOOR_OF[name] < FLOOR_OF["cli"])
#: Below ``runs``: none of these imports it.
BELOW_RUNS = tuple(name for name in FLOOR_OF if FLOOR_OF[name] < FLOOR_OF["runs"])
#: Old import paths kept for one release after their module moved (tests/test_deprecated_aliases.py).
#: Each imports the module's new home, often a floor above its own, only to re-export it; left out
#: of the floors, since a user's old import, not the package, is what they serve.
DEPRECATED_ALIASES = frozenset({
    "yafs_safetail.settings.world_recipe",
    "yafs_safetail.edge.mobility",
    *(f"yafs_safetail.contention.{name}" for name in ("sweep", "sweep_config", "sweep_checks", "sweep_learners",
                                                      "sweep_report", "mechanism")),
})


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported(path: Path, module: str) -> Iterator[str]:
    """Every yafs_safetail module ``path`` imports, anywhere in it (``from yafs_safetail import
    x`` names ``yafs_safetail.x``, which is a module or the package itself)."""
    package_parts = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[:len(package_parts) - node.level + 1]
                target = ".".join([*base, *([node.module] if node.module else [])])
            else:
                target = node.module or ""
            yield target
            yield from (f"{target}.{alias.name}" for alias in node.names)


def _floor(module: str) -> str | None:
    """A module's package below yafs_safetail (``sim``), or its own name for a root module
    (``cli``); None for the package itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "yafs_safetail" else None


def _modules() -> dict[str, Path]:
    return {_module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))
            if _module_name(path) not in DEPRECATED_ALIASES}


def _module_edges() -> set[tuple[str, str]]:
    """(module, imported module) for every existing module's imports of another package's."""
    known = _modules()
    found: set[tuple[str, str]] = set()
    for module, path in known.items():
        source = _floor(module)
        if source is None:
            continue
        for target in _imported(path, module):
            # A name imported from a module (yafs_safetail.cli.load_list) counts as that module.
            while target and target not in known:
                target = target.rpartition(".")[0]
            floor = _floor(target)
            if floor is not None and floor != source:
                found.add((module, target))
    return found


def _edges() -> dict[tuple[str, str], list[str]]:
    """(floor, imported floor) -> the modules behind that edge, for every existing module."""
    edges: dict[tuple[str, str], list[str]] = {}
    for module, target in sorted(_module_edges()):
        edges.setdefault((_floor(module) or "", _floor(target) or ""), []).append(module)
    return edges


def _climbing(module_edges: set[tuple[str, str]]) -> list[str]:
    """The imports of a package on the importer's own floor or above (none may climb: what a
    declaration needs from above is ``Provided`` to it, ``settings.declare``)."""
    return sorted(f"{module} imports {target}" for module, target in module_edges
                  if FLOOR_OF[_floor(target) or ""] >= FLOOR_OF[_floor(module) or ""])


def test_every_package_and_root_module_has_a_floor() -> None:
    placed = {_floor(module) for module in _modules()} - {None}
    assert placed <= set(FLOOR_OF), f"no floor in FLOORS: {sorted(placed - set(FLOOR_OF))}"


def test_no_module_imports_its_own_floor_or_one_above() -> None:
    assert _climbing(_module_edges()) == []


def test_the_floors_check_sees_a_lower_floor_importing_a_higher_one() -> None:
    assert _climbing({("yafs_safetail.settings.world", "yafs_safetail.edge.calibration"),
                      ("yafs_safetail.sim.env", "yafs_safetail.contention.env"),
                      ("yafs_safetail.edge.world", "yafs_safetail.settings.world")}) == [
        "yafs_safetail.settings.world imports yafs_safetail.edge.calibration",
        "yafs_safetail.sim.env imports yafs_safetail.contention.env"]


def test_the_parser_sees_lazy_and_type_checking_imports(tmp_path: Path) -> None:
    source = tmp_path / "sample.py"
    source.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from yafs_safetail.runs import grid\n"
                      "def f():\n    import yafs_safetail.cli\n")
    found = set(_imported(source, "yafs_safetail.sample"))
    assert {"yafs_safetail.runs.grid", "yafs_safetail.cli"} <= found


@pytest.mark.parametrize("floor", NOT_CLI)
def test_nothing_below_the_commands_imports_cli(floor: str) -> None:
    offenders = sorted({module for (source, target), modules in _edges().items() if source == floor and target == "cli"
                        for module in modules})
    assert offenders == [], f"{floor} imports cli: {offenders}"


@pytest.mark.parametrize("floor", BELOW_RUNS)
def test_nothing_below_runs_imports_it(floor: str) -> None:
    offenders = sorted({module for (source, target), modules in _edges().items()
                        if source == floor and target == "runs" for module in modules})
    assert offenders == [], f"{floor} imports runs: {offenders}"


def test_the_settings_floor_stands_on_the_light_root_modules_alone() -> None:
    allowed = {"defaults"}
    found = {_floor(target) for module, target in _module_edges() if _floor(module) == "settings"}
    assert found <= allowed, f"settings imports {sorted(found - allowed)}"


def test_no_import_cycle_between_packages() -> None:
    graph: dict[str, set[str]] = {}
    for source, target in _edges():
        graph.setdefault(source, set()).add(target)
    cycle = _a_cycle(graph)
    assert cycle is None, " -> ".join(cycle or []) + ": " + "; ".join(
        f"{a} -> {b} in {sorted(set(_edges()[(a, b)]))}" for a, b in zip(cycle or [], (cycle or [])[1:], strict=False))


def _a_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a path that returns to its start, or None."""
    state: dict[str, str] = {}

    def visit(node: str, path: list[str]) -> list[str] | None:
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return [*path[path.index(nxt):], node, nxt] if nxt in path else [*path, node, nxt]
            if nxt not in state:
                found = visit(nxt, [*path, node])
                if found:
                    return found
        state[node] = "done"
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start, [])
            if found:
                return found
    return None


def _documented_packages() -> set[str]:
    """The packages docs/architecture.md's "Layers" block names, as dotted paths below
    yafs_safetail (``methods.safetail``): a line ``  name/`` opens a package, indented by two
    spaces per level."""
    text = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = text.split("## Layers", 1)[1].split("```", 2)[1]
    named: set[str] = set()
    parents: list[str] = []
    for line in block.splitlines()[2:]:  # after "yafs_safetail/"
        if re.match(r"^\S", line):  # the checkout's other folders: experiments/, examples/...
            break
        match = re.match(r"^( {2}| {4})([a-z_]+)/(\s|$)", line)
        if not match:
            continue
        depth = len(match.group(1)) // 2 - 1
        parents = [*parents[:depth], match.group(2)]
        named.add(".".join(parents))
    return named


def test_docs_architecture_names_every_package_and_no_other():
    packages = {".".join(path.parent.relative_to(PACKAGE).parts)
                for path in PACKAGE.rglob("__init__.py") if path.parent != PACKAGE}
    assert _documented_packages() == packages


def test_every_package_says_what_it_holds():
    for init in PACKAGE.rglob("__init__.py"):
        docstring = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert docstring and len(docstring.split()) >= 8, f"{init}: no docstring saying what it holds"


def test_a_conversion_from_above_is_provided_by_its_floor_not_imported() -> None:
    # settings.experiment declares --method; the methods package, a floor above, provides the
    # conversion of its specs into users' policies when it is imported.
    from yafs_safetail.settings.declare import Provided, field_of, setting_of
    from yafs_safetail.settings.experiment import USER_METHODS, Task

    assert setting_of(field_of(Task, "methods")).from_cli is USER_METHODS
    import yafs_safetail.methods  # noqa: F401  (provides it)
    from yafs_safetail.methods.registry import UserMethod

    (method,) = USER_METHODS(["Mine=yafs_safetail.methods.baselines:LeastLoadedTwo"])
    assert isinstance(method, UserMethod) and method.name == "Mine"
    with pytest.raises(RuntimeError, match="--flag: nothing provides the conversion; import some.package first"):
        Provided("--flag", "some.package")(["x"])
