"""Deprecated alias of :mod:`yafs_safetail.edge.routes` (renamed: it holds the user's routes, read
from a file or drawn by random waypoint, beside ``edge.movement`` and ``edge.positions``; kept one
release for code that imports the old path, then removed)."""

from __future__ import annotations

import warnings

from yafs_safetail.edge.routes import *  # noqa: F403 (the old path's names, unchanged)

# A module's body runs once per interpreter, so the warning is given once, at the importer.
warnings.warn("yafs_safetail.edge.mobility is deprecated; import yafs_safetail.edge.routes",
              DeprecationWarning, stacklevel=2)
