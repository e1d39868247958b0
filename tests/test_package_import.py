"""Importing the package is light (the command line's --help needs nothing heavy) and still
makes the Gymnasium id available, whichever of the two is imported first."""

from __future__ import annotations

import subprocess
import sys

import pytest


def _run(code: str) -> str:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip()


def test_package_import_loads_neither_numpy_nor_gymnasium():
    loaded = _run("import sys, yafs_safetail; "
                  "print(sorted(m for m in ('numpy', 'gymnasium', 'pandas') if m in sys.modules))")
    assert loaded == "[]"


@pytest.mark.parametrize("imports", [
    "import yafs_safetail; import gymnasium",
    "import gymnasium; import yafs_safetail",
    "import yafs_safetail, importlib; importlib.reload(yafs_safetail); import gymnasium",
], ids=["package first", "gymnasium first", "package reloaded"])
def test_env_id_registered_whichever_is_imported_first(imports):
    entry = _run(f"{imports}; print(gymnasium.spec(yafs_safetail.ENV_ID).entry_point)")
    assert entry == "yafs_safetail.sim.env:SafeTailEnv"
