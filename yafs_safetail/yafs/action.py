"""YAFS3's ``yafs.action``: the base of actions run on mobile agents (a placeholder there too)."""

from __future__ import annotations

from typing import Any


class generic_action:  # noqa: N801 - YAFS name
    """An action bound to a simulation; :meth:`action` does nothing unless overridden.

    Args:
        sim: the :class:`~yafs_safetail.yafs.core.Sim`.
    """

    def __init__(self, sim: Any) -> None:
        self.sim = sim

    def action(self, mobile_agent: Any) -> None:
        """Act on ``mobile_agent`` (override)."""
        return None
