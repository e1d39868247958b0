"""Text to value for the command line: the argparse ``type`` of every option that is not a
setting's own check (lists of seeds, loads, rates) and of the checks themselves.

Standard library only, so that ``--help`` and a bad argument answer before anything heavy
loads. ``cli`` re-exports every name, for the commands and the scripts outside the package.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def user_path(text: str) -> Path:
    """An argparse type for every path option: ``~`` and ``~user`` expanded, as a shell would.

    A shell leaves ``~`` alone when it is quoted or follows ``=`` (``--out=~/x``); without this
    the run would create a folder named ``~`` in the working folder.
    """
    return Path(text).expanduser()


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not value > 0 or value == float("inf"):  # also refuses nan
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """An argparse type: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative number, got {text!r}") from None
    if not value >= 0 or value == float("inf"):  # also refuses nan
        raise argparse.ArgumentTypeError(f"expected a non-negative number, got {text!r}")
    return value


def _integer(text: str, smallest: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a {what} integer, got {text!r}") from None
    if value < smallest:
        raise argparse.ArgumentTypeError(f"expected a {what} integer, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An argparse type: an integer >= 1."""
    return _integer(text, 1, "positive")


def non_negative_int(text: str) -> int:
    """An argparse type: an integer >= 0 (a seed)."""
    return _integer(text, 0, "non-negative")


def int_list(text: str) -> tuple[int, ...]:
    """An argparse type: comma-separated non-negative integers, at least one."""
    try:
        values = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or min(values) < 0:
        raise argparse.ArgumentTypeError(f"expected non-negative integers, got {text!r}")
    return values


def positive_float_list(text: str) -> tuple[float, ...]:
    """An argparse type: distinct positive numbers, comma-separated, returned ascending."""
    try:
        values = tuple(positive_float(part) for part in text.split(","))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive numbers, got {text!r}") from None
    if len(set(values)) != len(values):
        raise argparse.ArgumentTypeError(f"expected distinct numbers, got {text!r}")
    return tuple(sorted(values))


def load_list(text: str) -> tuple[float, ...]:
    """An argparse type: distinct offered loads in (0, 10), comma-separated, returned ascending."""
    try:
        loads = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not loads or any(not 0 < load < 10 for load in loads) or len(set(loads)) != len(loads):
        raise argparse.ArgumentTypeError(f"expected distinct loads in (0, 10), got {text!r}")
    return tuple(sorted(loads))


def distinct_int_list(text: str) -> tuple[int, ...]:
    """:func:`int_list` with no value given twice (a repeated seed would count twice)."""
    values = int_list(text)
    repeated = sorted({v for v in values if values.count(v) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(
            f"{repeated[0]} is given twice in {text!r}; a repeated seed would count twice")
    return values


def speed_range(text: str) -> tuple[float, float]:
    """An argparse type: ``slowest,fastest`` in m/s, 0 < slowest <= fastest, or ``0,0`` (at rest)."""
    parts = text.split(",")
    try:
        slowest, fastest = (float(part) for part in parts) if len(parts) == 2 else (math.nan, math.nan)
    except ValueError:
        slowest = fastest = math.nan
    if not is_speed_range((slowest, fastest)):
        raise argparse.ArgumentTypeError(f"expected slowest,fastest in m/s with 0 < slowest <= fastest "
                                         f"(or 0,0 for at rest), got {text!r}")
    return slowest, fastest


def is_speed_range(value: object) -> bool:
    """Whether ``value`` is a (slowest, fastest) pair random waypoint accepts."""
    if not (isinstance(value, tuple | list) and len(value) == 2):
        return False
    if not all(isinstance(v, float | int) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        return False
    slowest, fastest = value
    return (slowest, fastest) == (0, 0) or 0 < slowest <= fastest
