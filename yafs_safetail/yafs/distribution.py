"""Inter-event time distributions: objects with ``.next()`` (YAFS names).

No global random state: random distributions draw from a ``numpy.random.Generator`` passed
as ``rng``, or from a generator built from their explicit ``seed``.
"""

from __future__ import annotations

import numpy as np


class Distribution:
    """Base class: ``next()`` returns the next inter-event time (simulation units)."""

    def __init__(self, name: str = "") -> None:
        self.name = name

    def next(self) -> float:
        """Return the next value."""
        raise NotImplementedError

    def __next__(self) -> float:
        return self.next()

    def __iter__(self) -> Distribution:
        return self


class deterministic_distribution(Distribution):  # noqa: N801 - YAFS name
    """Always ``time``.

    Args:
        time: the constant inter-event time.
        name: a label.
    """

    def __init__(self, time: float, name: str = "") -> None:
        super().__init__(name)
        self.time = time

    def next(self) -> float:
        return self.time


class deterministicDistributionStartPoint(Distribution):  # noqa: N801 - YAFS name
    """``start`` first, then always ``time``."""

    def __init__(self, start: float, time: float, name: str = "") -> None:
        super().__init__(name)
        self.start = start
        self.time = time
        self._started = False

    def next(self) -> float:
        if not self._started:
            self._started = True
            return self.start
        return self.time


class exponential_distribution(Distribution):  # noqa: N801 - YAFS name
    """Exponential inter-event times of mean ``lambd``, truncated to integers, at least 1.

    The truncation and the floor of 1 are YAFS's behaviour. With ``rng=None`` the draws come
    from numpy's legacy ``RandomState(seed)``, the stream YAFS itself uses, so a ported
    script reproduces YAFS's arrivals; pass ``rng`` (a ``numpy.random.Generator``) to use
    the modern generator instead, and ``integer=False`` for untruncated times.

    Args:
        lambd: the mean inter-event time (YAFS's ``lambda`` is a mean, not a rate).
        seed: explicit seed when ``rng`` is not given.
        rng: a generator to draw from.
        integer: truncate to integers with a floor of 1 (YAFS).
        name: a label.
    """

    def __init__(
        self,
        lambd: float,
        seed: int = 1,
        rng: np.random.Generator | None = None,
        integer: bool = True,
        name: str = "",
    ) -> None:
        super().__init__(name)
        if lambd <= 0:
            raise ValueError(f"exponential_distribution: lambd must be positive, got {lambd}")
        self.l = lambd
        self.integer = integer
        self._draw = rng.exponential if rng is not None else np.random.RandomState(seed).exponential

    def next(self) -> float:
        value = float(self._draw(self.l))
        if not self.integer:
            return value
        return max(int(value), 1)


class uniformDistribution(Distribution):  # noqa: N801 - YAFS name
    """Uniform integer inter-event times in ``[min, max]`` (inclusive), as YAFS draws them.

    Args:
        min: lower bound.
        max: upper bound.
        seed: explicit seed when ``rng`` is not given.
        rng: a generator to draw from.
        name: a label.
    """

    def __init__(
        self,
        min: int,  # noqa: A002 - YAFS keyword name
        max: int,  # noqa: A002 - YAFS keyword name
        seed: int = 1,
        rng: np.random.Generator | None = None,
        name: str = "",
    ) -> None:
        super().__init__(name)
        if max < min:
            raise ValueError(f"uniformDistribution: max ({max}) < min ({min})")
        self.min = min
        self.max = max
        self._rng = rng if rng is not None else np.random.default_rng(seed)

    def next(self) -> float:
        return int(self._rng.integers(self.min, self.max, endpoint=True))
