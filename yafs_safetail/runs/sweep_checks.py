"""The contention sweeps' own checks and option parsers (loads, failure levels, methods,
learners): light, so the sweep commands' ``--help`` loads nothing heavy."""

from __future__ import annotations

import argparse
import math
from typing import Any

from yafs_safetail.methods.objectives import objective_names
from yafs_safetail.settings.checks import Check
from yafs_safetail.settings.parse import load_list


def _method_names(text: str) -> tuple[str, ...]:
    """``--methods``: comma-separated method names (checked when the sweep builds them)."""
    return tuple(name.strip() for name in text.split(",") if name.strip())


#: The methods a sweep may be given (any baseline name; checked when the policies are built).
METHOD_NAMES = Check("comma-separated method names",
                     lambda v: isinstance(v, tuple) and all(isinstance(m, str) for m in v), _method_names)


def _learner_names(text: str) -> tuple[str, ...]:
    """``--objectives``: distinct objectives' names, comma-separated, in the order given."""
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    if not names or len(set(names)) != len(names) or any(name not in objective_names() for name in names):
        raise argparse.ArgumentTypeError(f"expected distinct names of {', '.join(objective_names())}, got {text!r}")
    return names


#: SafeTail's learners: distinct objectives' names (methods.objectives).
LEARNERS = Check(f"distinct names of {', '.join(objective_names())}", lambda v: isinstance(v, tuple) and bool(v) and len(
    set(v)) == len(v) and all(name in objective_names() for name in v), _learner_names)


def _is_load(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, float | int) and 0 < value < 10


#: Offered loads: distinct utilisations in (0, 10).
LOADS = Check("distinct loads in (0, 10)",
              lambda v: isinstance(v, tuple) and len(set(v)) == len(v) and all(_is_load(x) for x in v), load_list)


def _one_load(text: str) -> float:
    """``--load``: one offered load in (0, 10)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not _is_load(value):
        raise argparse.ArgumentTypeError(f"expected a load in (0, 10), got {text!r}")
    return value


#: The failure sweep's one offered load.
ONE_LOAD = Check("a load in (0, 10)", _is_load, _one_load)


def _is_failure_level(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, float | int) and 0 <= value < 1


def failure_level_list(text: str) -> tuple[float, ...]:
    """``--failure-levels``: distinct per-server down probabilities in [0, 1), comma-separated,
    returned ascending (the sweep's points rise)."""
    try:
        levels = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not levels or not all(_is_failure_level(level) for level in levels) or len(set(levels)) != len(levels):
        raise argparse.ArgumentTypeError(f"expected distinct probabilities in [0, 1), got {text!r}")
    return tuple(sorted(levels))


#: Failure levels: distinct stationary down probabilities in [0, 1).
FAILURE_LEVELS = Check("distinct probabilities in [0, 1)", lambda v: isinstance(v, tuple) and bool(v) and len(
    set(v)) == len(v) and all(_is_failure_level(x) for x in v), failure_level_list)
