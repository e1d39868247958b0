"""The method registry: built-in names, report order, and users' policies named on the command line."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.methods import MinLoadX, Oracle, Policy, PolicyError, RandX, make_baseline
from yafs_safetail.methods.registry import (
    UserMethod,
    baseline_names,
    baselines_of,
    parse_method,
    sort_methods,
)
from yafs_safetail.runs.experiment import REPOSITORY

EXAMPLE = REPOSITORY / "examples" / "custom_policy" / "nearest_free.py"


def test_names_parse_and_sort_in_report_order():
    assert parse_method("MinProp-3") == ("MinProp", 3) and parse_method("Mine") == ("Mine", None)
    names = ["Mine", "MinProp-1", "Rand-2", "Oracle", "Rand-1", "SafeTail", "MinLoad-1", "Alpha"]
    assert sort_methods(names) == ["SafeTail", "Oracle", "Rand-1", "Rand-2", "MinLoad-1",
                                   "MinProp-1", "Alpha", "Mine"]
    assert baselines_of(names, "Rand") == ["Rand-1", "Rand-2"]
    assert baseline_names((1, 2)) == ["Oracle", "Rand-1", "Rand-2", "MinLoad-1", "MinLoad-2", "MinProp-1", "MinProp-2"]


def test_make_baseline_builds_each_family_and_rejects_unknown_names():
    rng = np.random.default_rng(0)
    assert isinstance(make_baseline("Oracle", 5, rng), Oracle)
    rand = make_baseline("Rand-2", 5, rng)
    assert isinstance(rand, RandX) and rand.name == "Rand-2"
    assert isinstance(make_baseline("MinLoad-1", 5, rng), MinLoadX)
    for bad in ("Rand-0", "Rand-6", "Fastest-1", "SafeTail"):
        with pytest.raises(PolicyError):
            make_baseline(bad, 5, rng)


def test_user_method_from_a_file_is_named_after_its_class_unless_named():
    method = UserMethod(f"{EXAMPLE}:NearestFree")
    assert method.name == "NearestFree"
    policy = method.make(5, np.random.default_rng(0))
    assert isinstance(policy, Policy) and policy.name == "NearestFree" and policy.n_servers == 5
    assert UserMethod(f"Nearest={EXAMPLE}:NearestFree").make(3, np.random.default_rng(0)).name == "Nearest"


def test_user_method_from_a_module(tmp_path, monkeypatch):
    (tmp_path / "my_policies.py").write_text(textwrap.dedent("""
        from yafs_safetail.methods import Policy

        class FirstServer(Policy):
            observes = False

            def choose(self, observation):
                return (0,)
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    policy = UserMethod("my_policies:FirstServer").make(4, np.random.default_rng(0))
    assert policy.choose(None) == (0,) and policy.name == "FirstServer"


@pytest.mark.parametrize(("spec", "fragment"), [
    ("no_colon_here", "expected path/to/file.py:ClassName"),
    ("missing/file.py:Thing", "no such file"),
    ("yafs_safetail_no_such_module:Thing", "cannot import"),
    (f"{EXAMPLE}:NoSuchClass", "is not a Policy subclass"),
    ("numpy:ndarray", "is not a Policy subclass"),
    (f"Oracle={EXAMPLE}:NearestFree", "taken by a built-in method"),
    (f"Rand-4={EXAMPLE}:NearestFree", "taken by a built-in method"),
])
def test_bad_user_methods_are_one_line_errors(spec, fragment):
    with pytest.raises(PolicyError, match=fragment) as caught:
        UserMethod(spec)
    assert "\n" not in str(caught.value) and spec in str(caught.value)


def test_a_user_file_that_fails_to_import_is_named(tmp_path):
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('boom')\n")
    with pytest.raises(PolicyError, match=r"broken.py failed to import: RuntimeError: boom"):
        UserMethod(f"{broken}:Anything")


def test_a_policy_whose_constructor_does_not_fit_is_named(tmp_path):
    path = Path(tmp_path / "needs_more.py")
    path.write_text(textwrap.dedent("""
        from yafs_safetail.methods import Policy

        class NeedsMore(Policy):
            def __init__(self, n_servers, rng, width):
                super().__init__(n_servers, rng)
    """))
    method = UserMethod(f"{path}:NeedsMore")
    with pytest.raises(PolicyError, match=r"cannot construct NeedsMore\(n_servers, rng\)"):
        method.make(5, np.random.default_rng(0))
