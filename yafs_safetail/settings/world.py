"""The world's settings a run may override, declared once for every world and command.

:class:`WorldOverrides` holds them: the experiment's configuration (``settings.experiment``'s
``WorldSetup``) and the contention world's (``contention.config.ContentionConfig``) both inherit
it, so each is an option of ``run_usecase.py``, ``reproduce_all.py`` and the sweeps, a keyword of
both Gymnasium environments and a field a campaign grid may set, from this one declaration.
:func:`apply_world_overrides` applies them to a world's ``edge.calibration.WorldSettings``, each
to the field of the same name.

Adding one is a field here (beside the ``WorldSettings`` field it overrides) and a test
(CONTRIBUTING.md shows one). Only light modules at import: the commands build their parsers from
this module before NumPy loads.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

from yafs_safetail.defaults import BASELINE_READINGS, TARGET_COMPUTES
from yafs_safetail.settings.declare import NON_NEGATIVE_NUMBER, POSITIVE_NUMBER, one_of, setting

if TYPE_CHECKING:
    from yafs_safetail.edge.calibration import WorldSettings


@dataclass(frozen=True)
class WorldOverrides:
    """The world's settings (``edge.calibration.WorldSettings`` fields of the same names) a run
    may set; None keeps the world's own value."""

    target_latency_s: float | None = setting(
        None, "a fixed target latency for every request, in seconds (default: Eq. 4's per-request "
        "heuristic, as in the paper)", check=POSITIVE_NUMBER, optional=True)
    load_peak_users: float | None = setting(
        None, "load level: background users on a server at its busiest minute (0 = idle, 4 = full at "
        "the peak; default: the preset world's, recorded in run.json)", check=NON_NEGATIVE_NUMBER, optional=True)
    target_compute: str | None = setting(
        None, "C(s_j) of Eq. 4: 'request', the median compute time at ν of the request's own input, "
        "or 'trace_median', the compute trace's median at ν for every request (default: the preset "
        "world's; deviation D11 in the documentation)", check=one_of(TARGET_COMPUTES), optional=True)
    baseline_reading: str | None = setting(
        None, "how MinLoad-x and MinProp-x choose: 'paper-text', the x best of all servers (§V-B), "
        "or 'original-code', the x best of three drawn at random per request, as the code behind "
        "the paper's numbers did (default: the preset world's; calibration rule 5 in the "
        "documentation)", check=one_of(BASELINE_READINGS), optional=True)

    def world_overrides(self) -> dict[str, Any]:
        """The overrides it sets (name: value; None is left out): a sweep point's settings record
        only these, so the run id of a point without any stays what it was before they existed."""
        return {name: getattr(self, name) for name in WORLD_OVERRIDES if getattr(self, name) is not None}


#: The overrides' names, in declaration order (the order they are applied and recorded).
WORLD_OVERRIDES: tuple[str, ...] = tuple(item.name for item in fields(WorldOverrides))


class WorldOverrideError(ValueError):
    """An override the world's settings refuse; the caller names it as its own option or field.

    Attributes:
        name: the setting's field name (one of :data:`WORLD_OVERRIDES`).
        value: the refused value.
    """

    def __init__(self, name: str, value: Any) -> None:
        super().__init__(f"{name}: {value!r} is out of range")
        self.name = name
        self.value = value


def apply_world_overrides(settings: WorldSettings,
                          config: WorldOverrides) -> tuple[WorldSettings, dict[str, Any]]:
    """The world's settings with the run's overrides applied, and the overrides that changed them.

    An override repeating the world's own value is left out of the second result: the world is
    then still the named one, and a run's record says nothing was overridden.

    Raises:
        WorldOverrideError: a value the world's settings refuse (out of range).
    """
    from yafs_safetail.edge.calibration import CalibrationError  # NumPy: once a world is read

    changed_by: dict[str, Any] = {}
    for name in WORLD_OVERRIDES:
        value = getattr(config, name)
        if value is None:
            continue
        try:
            changed = dataclasses.replace(settings, **{name: value})
        except (CalibrationError, TypeError):  # (TypeError: a value of the wrong type)
            raise WorldOverrideError(name, value) from None
        if changed != settings:
            changed_by[name] = value
        settings = changed
    return settings, changed_by
