"""What values a setting accepts: :class:`Check`, the checks the declarations share, and
:class:`Names`, choices a higher floor adds to.

The declarations (``settings.declare.setting``) name one of these; the command line's parsers
and the configurations' own checks (``settings.declare.check_config``) both read it. Standard
library only, as every module of this floor.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from yafs_safetail.defaults import FIGURE_FORMATS, figure_formats
from yafs_safetail.settings.parse import (
    is_speed_range,
    non_negative_float,
    non_negative_int,
    positive_float,
    positive_int,
    speed_range,
)


@dataclass(frozen=True)
class Check:
    """What values a setting accepts, for the command line and for values set in Python.

    Attributes:
        description: the accepted values in words (``"a positive number"``), for error
            messages (:attr:`what`); a callable when they are :class:`Names` a higher floor adds to.
        accepts: whether a Python value is acceptable (``None`` is handled by the caller).
        parse: the argparse ``type``: text to value, raising ``argparse.ArgumentTypeError``.
        choices: the accepted values when they are a short list (argparse shows them).
    """

    description: str | Callable[[], str]
    accepts: Callable[[Any], bool]
    parse: Callable[[str], Any] | None = None
    choices: Sequence[Any] | None = None

    @property
    def what(self) -> str:
        """The accepted values in words, as they are now."""
        return self.description() if callable(self.description) else self.description


class Names(Sequence[str]):
    """Names a higher floor adds to as it defines them, so that a setting declared on this floor
    accepts every one without importing that floor (``settings.experiment.OBJECTIVE_NAMES``: each
    class of ``methods.objectives`` adds its name). A :func:`one_of` check, argparse's choices and
    the help read it when they run, not when the setting is declared."""

    def __init__(self, names: Sequence[str] = ()) -> None:
        self._names: list[str] = list(names)

    def add(self, name: str) -> None:
        """Add ``name`` (once; the order is the order names are first added)."""
        if name not in self._names:
            self._names.append(name)

    def __getitem__(self, index: Any) -> Any:
        return self._names[index]

    def __len__(self) -> int:
        return len(self._names)

    def __repr__(self) -> str:
        return f"Names({self._names!r})"


def is_number(value: Any) -> bool:
    """A finite int or float (never a bool): what every numeric check starts from."""
    return not isinstance(value, bool) and isinstance(value, float | int) and math.isfinite(value)


def is_integer(value: Any) -> bool:
    """An int (never a bool)."""
    return not isinstance(value, bool) and isinstance(value, int)


POSITIVE_NUMBER = Check("a positive number", lambda v: is_number(v) and v > 0, positive_float)
NON_NEGATIVE_NUMBER = Check("a non-negative number", lambda v: is_number(v) and v >= 0,
                            non_negative_float)
POSITIVE_INTEGER = Check("a positive integer", lambda v: is_integer(v) and v >= 1, positive_int)
NON_NEGATIVE_INTEGER = Check("a non-negative integer", lambda v: is_integer(v) and v >= 0,
                             non_negative_int)
BOOLEAN = Check("true or false", lambda v: isinstance(v, bool))


def one_of(choices: Sequence[Any], parse: Callable[[str], Any] | None = None) -> Check:
    """A check for one of a few values (argparse lists them; ``parse`` turns text into one).
    :class:`Names` stay live: the values accepted are those added by the time a value is checked."""
    if isinstance(choices, Names):
        names = choices
        return Check(lambda: "one of " + ", ".join(names), lambda v: isinstance(v, str) and v in names, parse, names)
    listed = ", ".join(str(c) for c in choices)
    return Check(f"one of {listed}", lambda v: not isinstance(v, bool) and v in choices, parse, tuple(choices))


def _redundancy_levels(text: str) -> tuple[int, ...]:
    try:
        levels = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not levels:
        raise argparse.ArgumentTypeError("expected at least one level")
    return levels


#: Redundancy levels: their range depends on the topology, checked when it is read.
FORMATS = Check(f"a list of {', '.join(FIGURE_FORMATS)}",
                lambda v: isinstance(v, tuple) and bool(v) and all(x in FIGURE_FORMATS for x in v),
                figure_formats)
LEVELS = Check("integers", lambda v: isinstance(v, tuple | list) and all(is_integer(x) for x in v),
               _redundancy_levels)


def _probability_below_one(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1), got {text!r}") from None
    if not 0.0 <= value < 1.0:  # also refuses nan
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1), got {text!r}")
    return value


#: Random waypoint's speeds: a range above zero, or (0, 0) for a user at rest.
SPEED_RANGE = Check("slowest,fastest in m/s with 0 < slowest <= fastest, or 0,0", is_speed_range, speed_range)

#: A server's stationary unavailability: 1 would be a server that is never up.
PROBABILITY_BELOW_ONE = Check(
    "a probability in [0, 1)",
    lambda v: not isinstance(v, bool) and isinstance(v, float | int) and math.isfinite(v) and 0 <= v < 1,
    _probability_below_one)
