"""Deprecated alias of :mod:`yafs_safetail.results.sweep_report` (moved there, beside the other reports, so that
``contention`` holds the contention world and its engine only; kept one release for code that
imports the old path, then removed).

It imports a floor above ``contention`` only to re-export it: ``tests/test_layers.py`` leaves the
deprecated aliases out of the floors it checks.
"""

from __future__ import annotations

import warnings

from yafs_safetail.results.sweep_report import *  # noqa: F403 (the old path's names, unchanged)

# A module's body runs once per interpreter, so the warning is given once, at the importer.
warnings.warn("yafs_safetail.contention.sweep_report is deprecated; import yafs_safetail.results.sweep_report",
              DeprecationWarning, stacklevel=2)
