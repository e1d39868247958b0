"""Deprecated alias of :mod:`yafs_safetail.worlds.recipe` (the world recipe moved there; kept one
release for code that imports the old path, then removed).

It imports a floor above ``settings`` only to re-export it: ``tests/test_layers.py`` leaves the
deprecated aliases out of the floors it checks.
"""

from __future__ import annotations

import warnings

from yafs_safetail.worlds.recipe import *  # noqa: F403 (the old path's names, unchanged)
from yafs_safetail.worlds.recipe import __all__ as __all__

# A module's body runs once per interpreter, so the warning is given once, at the importer.
warnings.warn("yafs_safetail.settings.world_recipe is deprecated; import yafs_safetail.worlds.recipe",
              DeprecationWarning, stacklevel=2)
