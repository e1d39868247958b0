"""The world's settings, each declared once: what a world is built with, and what a run may override.

:class:`WorldSettings` holds every choice the world's construction depends on beyond the traces
and the topology (``edge.calibration`` names the worlds made of them: ``landed``,
``calibrated``...); each field is declared with :func:`~yafs_safetail.settings.declare.setting`
(type, default, help, check), and its checks are those declarations'.

:class:`WorldOverrides` holds the ones a run may set: the experiment's configuration
(``settings.experiment``'s ``WorldSetup``) and the contention world's
(``contention.config.ContentionConfig``) both inherit it, so each is an option of
``run_usecase.py``, ``reproduce_all.py`` and the sweeps, a keyword of both Gymnasium environments
and a field a campaign grid may set. Each override is the :class:`WorldSettings` field of its name
(``same_as``: its help and check written once); :func:`apply_world_overrides` applies them to a
world's settings.

Adding one is a :class:`WorldSettings` field, its ``same_as`` line in :class:`WorldOverrides`, and
a test (CONTRIBUTING.md shows one). Standard library and ``defaults`` only: the commands build
their parsers from this module before NumPy loads, and ``edge`` builds its worlds from it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any

from yafs_safetail.defaults import BASELINE_READINGS, TARGET_COMPUTES
from yafs_safetail.settings.checks import (
    NON_NEGATIVE_NUMBER,
    POSITIVE_NUMBER,
    Check,
    is_integer,
    is_number,
    one_of,
)
from yafs_safetail.settings.declare import refused_field, same_as, setting

#: How the servers' load traces start an episode (:attr:`WorldSettings.load_start`).
LOAD_STARTS = ("shared", "per_server")

#: ρ_i per direction as a fraction of a ping RTT: above 0, at most the whole round trip.
RTT_FRACTION = Check("a number in (0, 1]", lambda v: is_number(v) and 0.0 < v <= 1.0)
#: The bandwidth share's exponent: the calibration's search range (``CALIBRATED_PARAMETERS``).
SHARE_EXPONENT = Check("a number in [0, 2]", lambda v: is_number(v) and 0.0 <= v <= 2.0)
#: ν of Eq. 4: a number of concurrent processes, at most the five the compute traces measure.
PROCESSES_NU = Check("an integer from 1 to 5", lambda v: is_integer(v) and 1 <= v <= 5)


class CalibrationError(ValueError):
    """A world's settings out of range, or the calibration file missing or malformed (one line
    naming the world or the file, and the field); ``edge.calibration`` re-exports it."""


@dataclass(frozen=True)
class WorldSettings:
    """Every choice the world's construction depends on beyond the traces and the topology.

    Each field's meaning is its declaration's help (docs/edge_model.md, docs/calibration.md);
    a value its check refuses is a :class:`CalibrationError` naming the world and the field.
    """

    name: str = setting("landed", "the world's label: landed, calibrated or a custom one (recorded "
                        "in run.json)")
    propagation_rtt_fraction: float = setting(
        1.0, "ρ_i per direction as a fraction of a measured ping RTT; Eq. 1 charges ρ_i on the way "
        "in and on the way out, so 0.5 makes a copy pay one round trip (the landed world used 1: "
        "two round trips)", check=RTT_FRACTION)
    load_start: str = setting(
        "shared", "shared: every server's load trace starts an episode at the same random minute; "
        "per_server: each server starts at its own random minute", check=one_of(LOAD_STARTS))
    load_peak_users: float = setting(
        4.0, "load level: background users on a server at its busiest minute (0 = idle, 4 = full at "
        "the peak; default: the preset world's, recorded in run.json)", check=NON_NEGATIVE_NUMBER)
    bandwidth_share_exponent: float = setting(
        0.0, "a server's λ at contention level c is the measured pool of level c divided by "
        "(1 + c)^this", check=SHARE_EXPONENT)
    fallback_compute_multiple: float | None = setting(
        None, "the on-device fallback latency as a multiple of the use case's median one-process "
        "compute time; None: the landed rule (the use case's fixed bound, raised to the "
        "topology's worst-case edge latency)", check=POSITIVE_NUMBER, optional=True)
    nu: int | None = setting(None, "ν of Eq. 4 for every use case; None: the use case's own (the "
                             "knee rule)", check=PROCESSES_NU, optional=True)
    target_latency_s: float | None = setting(
        None, "a fixed target latency for every request, in seconds (default: Eq. 4's per-request "
        "heuristic, as in the paper)", check=POSITIVE_NUMBER, optional=True)
    target_compute: str = setting(
        "trace_median", "C(s_j) of Eq. 4: 'request', the median compute time at ν of the request's own "
        "input, or 'trace_median', the compute trace's median at ν for every request (default: the "
        "preset world's; deviation D11 in the documentation)", check=one_of(TARGET_COMPUTES))
    baseline_reading: str = setting(
        "paper-text", "how MinLoad-x and MinProp-x choose: 'paper-text', the x best of all servers "
        "(§V-B), or 'original-code', the x best of three drawn at random per request, as the code "
        "behind the paper's numbers did (default: the preset world's; calibration rule 5 in the "
        "documentation)", check=one_of(BASELINE_READINGS))

    def __post_init__(self) -> None:
        bad = refused_field(self)  # the declarations' checks, worded as a world's
        if bad is not None:
            raise CalibrationError(f"world settings {self.name!r}: {bad}={getattr(self, bad)!r} is out of range")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class WorldOverrides:
    """The world's settings (:class:`WorldSettings` fields of the same names) a run may set;
    None keeps the world's own value."""

    target_latency_s: float | None = same_as(WorldSettings, "target_latency_s", None)
    load_peak_users: float | None = same_as(WorldSettings, "load_peak_users", None, optional=True)
    target_compute: str | None = same_as(WorldSettings, "target_compute", None, optional=True)
    baseline_reading: str | None = same_as(WorldSettings, "baseline_reading", None, optional=True)

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
