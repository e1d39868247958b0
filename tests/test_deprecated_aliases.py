"""Modules that moved keep their old import path for one release: the old path gives the new
module's names (the same objects) and says once, as a DeprecationWarning, where they went."""

from __future__ import annotations

import importlib
import sys
import warnings

import pytest
from test_layers import DEPRECATED_ALIASES

#: Old path -> new path.
MOVED = {
    "yafs_safetail.settings.world_recipe": "yafs_safetail.worlds.recipe",
    **{f"yafs_safetail.contention.{name}": f"yafs_safetail.runs.{name}"
       for name in ("sweep", "sweep_config", "sweep_checks", "sweep_learners", "mechanism")},
    "yafs_safetail.contention.sweep_report": "yafs_safetail.results.sweep_report",
    "yafs_safetail.edge.mobility": "yafs_safetail.edge.routes",
}


def test_every_alias_is_listed_for_the_floors_test() -> None:
    assert set(MOVED) == set(DEPRECATED_ALIASES)


@pytest.mark.parametrize("old", sorted(MOVED))
def test_the_old_path_gives_the_new_names_and_warns_once(old: str) -> None:
    new = importlib.import_module(MOVED[old])
    sys.modules.pop(old, None)  # as in a fresh interpreter: the module body runs again
    with pytest.warns(DeprecationWarning, match=MOVED[old].replace(".", r"\.")):
        alias = importlib.import_module(old)
    names = getattr(new, "__all__", None) or [name for name in vars(new) if not name.startswith("_")]
    assert names and all(getattr(alias, name) is getattr(new, name) for name in names)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a second import is the cached module: no warning
        importlib.import_module(old)
