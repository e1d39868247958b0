"""How the edge world is built where the paper is silent: readings and calibrated parameters.

The paper never published the numbers that decide most of its results: how the load trace
maps to server load (how often a server is full), how a server's bandwidth is shared, how long
the on-device fallback takes, and ν of the target latency. :class:`WorldSettings` collects them
with one physically meaningful rule each, and two readings of the paper's text:

* ``landed``: the first release's world (docs/edge_model.md), kept so that ``paper-literal``
  results stay what they were.
* ``calibrated``: the readings of docs/deviations.md D7 and D11, ν by the knee rule, plus the
  parameters fitted by ``experiments/calibrate.py`` without the learner, to what the paper's
  use-case-1 numbers imply about the x = 1 baselines' latency over Oracle's
  (docs/calibration.md), stored with their provenance in ``calibration.json`` next to this
  module.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

# What C(s_j) of Eq. 4 is; in defaults.py, since the command line lists them before anything loads.
from yafs_safetail.defaults import TARGET_COMPUTES as TARGET_COMPUTES

# The settings themselves are declared once, on the settings floor (each field's type, default,
# help and check); this module names the worlds made of them and reads the calibration.
from yafs_safetail.settings.world import LOAD_STARTS as LOAD_STARTS
from yafs_safetail.settings.world import CalibrationError as CalibrationError
from yafs_safetail.settings.world import WorldSettings as WorldSettings

#: The calibrated values and their provenance (written by ``experiments/calibrate.py``).
CALIBRATION_FILE = Path(__file__).with_name("calibration.json")
#: Which seeds may choose anything and which only report (docs/calibration.md).
SEED_SETS_FILE = Path(__file__).with_name("seed_sets.json")
SEED_SETS = ("world_calibration", "learner_calibration", "held_out", "fresh_held_out", "refit_held_out",
             "uc3_scale_held_out", "mobility_report", "target_held_out",
             "method_held_out")

WORLD_NAMES = ("landed", "calibrated", "calibrated-v1")

#: The parameters calibrate.py fits, with the range it searches and what each one means.
CALIBRATED_PARAMETERS: Mapping[str, tuple[float, float, str]] = {
    "load_peak_users": (2.5, 5.0, "active users a server has at its load device's busiest minute "
                                  "(the trace is min-max scaled onto 0..this, capped at the "
                                  "maximum load; at the maximum a server refuses)"),
    "bandwidth_share_exponent": (0.0, 2.0, "a server's measured WiFi bandwidth at c other active "
                                           "users is shared as 1/(1+c)^this (0: as measured, "
                                           "1: equally among them, assumption ii; above 1: "
                                           "contention costs more than an equal share, as "
                                           "WiFi collisions and back-off do)"),
    "fallback_compute_multiple": (4.0, 16.0, "the on-device lightweight version takes this many "
                                             "times the use case's median one-process edge "
                                             "compute time"),
}


LANDED = WorldSettings()
#: The first calibration's world (2026-11-24: fitted with SafeTail inside the objective, ν = 2),
#: kept because the contention world's documented figures were measured in it
#: (docs/contention.md); the paper's presets use today's ``calibrated``.
CALIBRATED_V1 = WorldSettings(name="calibrated-v1", propagation_rtt_fraction=0.5,
                              load_start="per_server", load_peak_users=3.75,
                              bandwidth_share_exponent=0.0, fallback_compute_multiple=8.0, nu=2,
                              target_compute="request")

#: The readings every calibrated world uses (docs/deviations.md D7, D11; ν None: each use
#: case's knee-rule ν, docs/calibration.md rule 2; the baselines as the original code chose,
#: rule 5); not fitted.
CALIBRATED_READINGS: Mapping[str, Any] = {"propagation_rtt_fraction": 0.5,
                                          "target_compute": "request", "nu": None,
                                          "baseline_reading": "original-code"}


def seed_set(name: str, path: Path | str = SEED_SETS_FILE) -> list[int]:
    """The seeds of one named set of ``seed_sets.json``.

    Raises:
        CalibrationError: an unknown set or a malformed file.
    """
    if name not in SEED_SETS:
        raise CalibrationError(f"{path}: unknown seed set {name!r}; valid: {', '.join(SEED_SETS)}")
    try:
        seeds = json.loads(Path(path).read_text())[name]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise CalibrationError(f"{path}: {name}: cannot be read ({error})") from None
    if not isinstance(seeds, list) or not seeds or not all(
            isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
        raise CalibrationError(f"{path}: {name}: expected a list of non-negative integers")
    return list(seeds)


def load_levels(users: np.ndarray, peak_users: float, max_load: int) -> np.ndarray:
    """Background users per minute and device: each device's count min-max scaled onto
    0..``peak_users``, rounded half up, capped at ``max_load``.

    With ``peak_users == max_load`` this is :func:`yafs_safetail.edge.traces.scale_load_levels`.
    A constant device maps to 0.
    """
    values = np.asarray(users, dtype=float)
    lo = values.min(axis=0)
    span = values.max(axis=0) - lo
    fraction = np.divide(values - lo, span, out=np.zeros_like(values), where=span > 0)
    return np.minimum(np.floor(peak_users * fraction + 0.5), max_load).astype(np.int64)


def read_calibration(path: Path | str = CALIBRATION_FILE) -> dict[str, Any]:
    """The calibration file: ``parameters``, ``readings`` and ``provenance``.

    Raises:
        CalibrationError: a missing or malformed file.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise CalibrationError(f"{path}: calibration file not found; run experiments/calibrate.py") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CalibrationError(f"{path}: not a readable JSON file ({error})") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: expected a JSON object")
    for key in ("parameters", "readings", "provenance"):
        if not isinstance(data.get(key), dict):
            raise CalibrationError(f"{path}: field {key!r} is missing or not an object")
    missing = [name for name in CALIBRATED_PARAMETERS if name not in data["parameters"]]
    if missing:
        raise CalibrationError(f"{path}: parameters.{missing[0]} is missing")
    return data


def calibrated_settings(values: Mapping[str, Any], readings: Mapping[str, Any] | None = None,
                        name: str = "calibrated") -> WorldSettings:
    """World settings from calibrated parameter values and the readings."""
    fields = dict(CALIBRATED_READINGS if readings is None else readings)
    fields.update({key: values[key] for key in CALIBRATED_PARAMETERS})
    if fields.get("nu") is not None:
        fields["nu"] = int(round(float(fields["nu"])))
    for key in ("load_peak_users", "bandwidth_share_exponent", "fallback_compute_multiple"):
        fields[key] = float(fields[key])
    try:
        return WorldSettings(name=name, **fields)
    except TypeError as error:
        raise CalibrationError(f"calibration: {error}") from None


def world_settings(name: str, calibration_file: Path | str = CALIBRATION_FILE) -> WorldSettings:
    """The named world: ``"landed"``, ``"calibrated"`` (read from the calibration file) or
    ``"calibrated-v1"`` (the first calibration, the contention world's default).

    Raises:
        CalibrationError: an unknown name or a bad calibration file.
    """
    if name == "landed":
        return LANDED
    if name == "calibrated-v1":
        return CALIBRATED_V1
    if name != "calibrated":
        raise CalibrationError(f"world: unknown world {name!r}; valid: {', '.join(WORLD_NAMES)}")
    data = read_calibration(calibration_file)
    return calibrated_settings(data["parameters"], data["readings"])
