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

#: Below the commands: none of these imports ``cli`` (only ``commands`` and ``cli`` itself do).
NOT_CLI = ("settings", "yafs", "edge", "methods", "sim", "contention", "runs", "results",
           "observation_space", "record", "defaults", "versions", "numerics", "logs", "stopping")
#: Below ``runs``: none of these imports it.
BELOW_RUNS = ("settings", "yafs", "edge", "methods", "sim", "contention", "results")


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


#: Old import paths kept for one release after their module moved (tests/test_deprecated_aliases.py).
#: Each imports the module's new home, often a floor above its own, only to re-export it; left out
#: of the floors, since a user's old import, not the package, is what they serve.
DEPRECATED_ALIASES = frozenset({
    "yafs_safetail.settings.world_recipe",
    *(f"yafs_safetail.contention.{name}" for name in ("sweep", "sweep_config", "sweep_checks", "sweep_learners",
                                                      "sweep_report", "mechanism")),
})


def _modules() -> dict[str, Path]:
    return {_module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))
            if _module_name(path) not in DEPRECATED_ALIASES}


def _edges() -> dict[tuple[str, str], list[str]]:
    """(floor, imported floor) -> the modules behind that edge, for every existing module."""
    known = _modules()
    edges: dict[tuple[str, str], list[str]] = {}
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
                edges.setdefault((source, floor), []).append(module)
    return edges


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


def test_the_settings_floor_stands_on_edge_methods_and_the_light_root_modules() -> None:
    allowed = {"defaults", "edge", "methods", "__init__"}
    found = {target for source, target in _edges() if source == "settings"}
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
