"""The method registry: built-in names, report order, and users' policies named on the command line."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from yafs_safetail.edge.observation import Observation
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


BAD_POLICIES = Path(__file__).resolve().parent / "bad_policies.py"


def observation_of_five_servers() -> Observation:
    five = np.arange(5)
    return Observation(
        server_uplink_bps=np.full(5, 2e7), server_downlink_bps=np.full(5, 2e7),
        server_memory_util=np.full(5, 0.1), server_cpu_util=np.full(5, 0.1),
        server_active_users=five % 3, server_median_propagation_s=0.01 * (five + 1),
        input_bytes=1e5, est_output_bytes=1e4, gamma=np.zeros(0), user_location=np.zeros(2),
        user_uplink_bps=2e7, user_downlink_bps=2e7, server_max_load=np.full(5, 4), step=0)


@pytest.mark.parametrize(("name", "fragments"), [
    ("Empty", ["Empty.choose() returned []", "no server", "0..4"]),
    ("OutOfRange", ["returned [5]", "server 5 does not exist", "0..4"]),
    ("Twice", ["returned (1, 1)", "server 1 is chosen twice"]),
    ("Mask", ["a mask of booleans", "np.flatnonzero"]),
    ("Text", ["returned '0'", "not a list of server indices", "type str"]),
    ("Raises", ["Raises.choose() raised IndexError", "bad_policies.py line"]),
    ("Hedger", ["dispatch 'hedge'", "the single-user world runs 'all'"]),
])
def test_a_policy_that_cannot_choose_is_named_with_what_is_wrong(name, fragments):
    from yafs_safetail.sim.selection import DISPATCH

    spec = f"{BAD_POLICIES}:{name}"
    with pytest.raises(PolicyError) as caught:
        UserMethod(spec).check_first_choice(5, np.random.default_rng(0), observation_of_five_servers(),
                                            DISPATCH)
    message = str(caught.value)
    assert message.startswith(f"--method {spec}: ") and "\n" not in message
    assert all(fragment in message for fragment in fragments), message


def test_a_policy_that_chooses_well_passes_the_first_choice_check():
    from yafs_safetail.sim.selection import DISPATCH

    for spec in (f"{EXAMPLE}:NearestFree", f"{BAD_POLICIES}:Later"):
        UserMethod(spec).check_first_choice(5, np.random.default_rng(0), observation_of_five_servers(),
                                            DISPATCH)


def test_a_constructor_that_raises_is_one_line_naming_its_line(tmp_path):
    path = tmp_path / "fragile.py"
    path.write_text(textwrap.dedent("""
        from yafs_safetail.methods import Policy

        class Fragile(Policy):
            def __init__(self, n_servers, rng):
                super().__init__(n_servers, rng)
                self.table = {}[n_servers]
    """))
    with pytest.raises(PolicyError, match=r"Fragile\(n_servers, rng\) raised KeyError: 5 \(fragile.py line 7\)"):
        UserMethod(f"{path}:Fragile").make(5, np.random.default_rng(0))
