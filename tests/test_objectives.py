"""The learning objectives (``methods.objectives``): each one's targets and rules, the registry,
SafeTail assembled in one place (``methods.safetail.assemble``), and no comparison of an
objective's name anywhere else in the package."""

from __future__ import annotations

import ast
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.defaults import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY, OBJECTIVES
from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.methods.objectives import (
    QTarget,
    Replay,
    TargetVector,
    Value,
    averages_networks,
    objective_named,
    objective_names,
    objectives_bringing,
    target_vector,
)
from yafs_safetail.methods.safetail.learner import target_vector as learner_target_vector
from yafs_safetail.methods.safetail.presets import get_preset

REPOSITORY = Path(__file__).resolve().parents[1]
PACKAGE = REPOSITORY / "yafs_safetail"
#: The one module that may compare an objective's name: the registry.
REGISTRY_MODULE = PACKAGE / "methods" / "objectives.py"


def test_the_registry_holds_the_shipped_objectives_in_order() -> None:
    assert objective_names()[:len(OBJECTIVES)] == OBJECTIVES
    assert [type(objective_named(name)) for name in OBJECTIVES] == [TargetVector, QTarget, Value]
    assert learner_target_vector is target_vector  # still importable where it was
    with pytest.raises(ValueError, match="unknown objective 'q-learning'; valid: target-vector, q-target, value"):
        objective_named("q-learning")


def test_only_value_averages_networks_and_brings_its_reward() -> None:
    assert objective_names(lambda objective: objective.averages_networks) == ("value",)
    assert objectives_bringing("latency-cost") == ("value",)
    assert not averages_networks(None) and averages_networks("value") and not averages_networks("q-target")
    value, paper = objective_named("value"), objective_named("target-vector")
    assert (value.output_activation, paper.output_activation) == ("linear", "softmax")
    assert (value.method_name, value.preset, value.dispatch, value.sweep_networks) == ("SafeTail-CA", "tuned", "tied", 3)
    assert paper.compile_loss() == "categorical_crossentropy"


def test_each_objective_stores_its_own_target() -> None:
    n_servers, n_actions = 3, 7
    row = np.zeros(n_actions, dtype=np.float32)
    objective_named("target-vector").write_target(row, 2, -0.05, n_servers)
    np.testing.assert_array_equal(row, target_vector(2, -0.05, n_servers).astype(np.float32))
    two_networks = np.zeros(2 * n_actions, dtype=np.float32)
    objective_named("value").write_target(two_networks, 4, 1.5, n_servers)  # any finite value
    assert np.flatnonzero(np.isfinite(two_networks)).tolist() == [4, 4 + n_actions]
    assert two_networks[4] == two_networks[4 + n_actions] == np.float32(1.5)
    with pytest.raises(ValueError, match="Eq. 5"):
        objective_named("q-target").write_target(row, 1, 0.5, n_servers)
    with pytest.raises(ValueError, match="out of range"):
        objective_named("value").write_target(row, n_actions, -1.0, n_servers)


def test_q_target_rounds_draw_only_tuples_with_a_next_state() -> None:
    stored = np.full((3, 3), np.nan, dtype=np.float32)
    stored[np.arange(3), [0, 2, 1]] = [-0.1, -0.2, -0.3]
    states = np.eye(3, dtype=np.float32)
    replay = Replay(states, stored, next_states=states[[1, 2, 0]], has_next=np.array([True, True, False]))
    q_target = objective_named("q-target")
    assert q_target.round_rows(replay).tolist() == [0, 1]
    targets = q_target.round_targets(replay, lambda x: np.asarray(x) * 0.5)
    # The taken entry: R + 0.95 · the next state's best output (0.5); R alone without a next state.
    np.testing.assert_allclose(targets[[0, 1, 2], [0, 2, 1]], [-0.1 + 0.475, -0.2 + 0.475, -0.3], rtol=1e-6)
    assert objective_named("value").round_rows(replay) == 3


def test_the_objectives_load_without_numpy() -> None:
    done = subprocess.run([sys.executable, "-c", "import sys, yafs_safetail.methods.objectives as o; "
                           "print(o.objective_names(), 'numpy' in sys.modules)"],
                          capture_output=True, text=True, cwd=REPOSITORY, timeout=120)
    assert done.stdout.split() == ["('target-vector',", "'q-target',", "'value')", "False"], done.stderr


# --- SafeTail assembled in one place ----------------------------------------------------------


@pytest.mark.parametrize("objective", OBJECTIVES)
def test_safetail_is_assembled_with_its_objectives_reward(objective: str) -> None:
    from yafs_safetail.methods.safetail.assemble import make_safetail

    use_case = get_use_case(1)
    scenario = load_scenario(DEFAULT_TOPOLOGY, DEFAULT_PLACEMENT)
    config = dataclasses.replace(get_preset("tuned", 1, train_steps=64), objective=objective)
    policy = make_safetail(use_case, scenario, config, 7, metadata={"world": "test"}, reward="no-free-miss",
                           dispatch="tied", name="SafeTail-X")
    assert (policy.name, policy.dispatch, policy.training) == ("SafeTail-X", "tied", True)
    assert policy.learner.metadata == {"use_case": 1, "world": "test"}
    assert policy.learner.config is config and policy.learner.n_servers == scenario.n_servers
    # The value learner brings its own reward (latency-cost: no Eq. 5 function); the others take
    # the one asked for.
    assert (policy._reward is None) == (objective == "value")


# --- no objective's name compared outside the registry ----------------------------------------


def _comparisons_of_names(path: Path, names: tuple[str, ...]) -> list[str]:
    """Every comparison in ``path`` against an objective's name (a string constant naming one,
    ``==`` / ``!=`` of an ``objective`` or ``learner`` value, a ``case`` on a name)."""
    where = path.relative_to(REPOSITORY) if path.is_relative_to(REPOSITORY) else path.name
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            named = any(isinstance(o, ast.Constant) and o.value in names for o in operands)
            equality = any(isinstance(op, ast.Eq | ast.NotEq) for op in node.ops)
            objective_value = any((isinstance(o, ast.Name) and o.id in ("objective", "learner"))
                                  or (isinstance(o, ast.Attribute) and o.attr in ("objective", "learner"))
                                  for o in operands)
            if named or (equality and objective_value):
                found.append((node.lineno, f"{where}:{node.lineno}: {ast.unparse(node)}"))
        elif isinstance(node, ast.MatchValue) and isinstance(node.value, ast.Constant) and node.value.value in names:
            found.append((node.lineno, f"{where}:{node.lineno}: case {node.value.value!r}"))
    return [hit for _, hit in sorted(found)]


def test_no_objective_name_is_compared_outside_the_registry() -> None:
    offenders = [hit for path in sorted(PACKAGE.rglob("*.py")) if path != REGISTRY_MODULE
                 for hit in _comparisons_of_names(path, objective_names())]
    assert offenders == [], "ask the objective (methods.objectives) instead:\n" + "\n".join(offenders)


def test_the_scan_sees_each_kind_of_comparison(tmp_path: Path) -> None:
    sample = tmp_path / "sample.py"
    sample.write_text('if config.objective == other:\n    pass\nif "value" not in objectives:\n    pass\n'
                      'match name:\n    case "q-target":\n        pass\nok = name in objective_names()\n')
    assert [hit.split(": ", 1)[0].rsplit(":", 1)[1] for hit in _comparisons_of_names(sample, OBJECTIVES)] == \
        ["1", "3", "6"]
