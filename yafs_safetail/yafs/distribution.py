"""Inter-event time distributions: objects with ``.next()`` (YAFS names).

YAFS3's own streams are kept: ``exponential_distribution`` / ``exponentialDistribution``
draw from a private ``numpy.random.RandomState(seed)``; ``uniformDistribution`` and
``exponentialDistributionStartPoint`` draw, as in YAFS3, from the global generators
(Python's ``random`` and numpy's legacy ``numpy.random``) unless given an ``rng`` (or a
``seed``), which is the way to keep a simulation independent of global state.
"""

from __future__ import annotations

import random
import warnings
from typing import Any

import numpy as np

#: Standard exponential draws taken at once by ``exponential_distribution``.
_BLOCK = 512
#: Draws of a seed's stream kept and shared by every ``exponential_distribution`` with that
#: seed; a distribution that needs more continues on a private generator.
_SHARED_DRAWS = 1 << 18


class _SeedStream:
    """The standard exponential draws of ``numpy.random.RandomState(seed)``, in order.

    Building a ``RandomState`` costs about as much as a thousand draws, and YAFS3's scripts
    build one per source, mostly with the same seed: the draws are made once per seed and
    read by every distribution with that seed (each keeping its own position).
    """

    __slots__ = ("seed", "rnd", "values")

    def __init__(self, seed: int) -> None:
        self.seed = seed
        self.rnd = np.random.RandomState(seed)
        self.values: list[float] = []

    def grow(self) -> bool:
        """Draw more (blocks of 8, 16, ... 512); False once the shared part is full."""
        values = self.values
        if len(values) >= _SHARED_DRAWS:
            return False
        size = min(len(values), _BLOCK) if values else 8
        values.extend(self.rnd.standard_exponential(size=size).tolist())
        return True


_STREAMS: dict[int, _SeedStream] = {}


def _seed_stream(seed: Any) -> _SeedStream | None:
    """The shared stream of an integer seed (None for other seeds: a private generator)."""
    if type(seed) is not int:
        return None
    stream = _STREAMS.get(seed)
    if stream is None:
        stream = _STREAMS[seed] = _SeedStream(seed)
    return stream


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
        self.started = False

    def next(self) -> float:
        if not self.started:
            self.started = True
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
        self._rng = rng
        self.seed = seed
        # YAFS's stream: a private legacy RandomState(seed). Its draws are scale * a
        # standard exponential, so standard ones are drawn in blocks and scaled one by one:
        # the same numbers as one call per draw, at a fraction of the cost. Integer seeds
        # read a stream shared by seed (_SeedStream) up to its end, then a private one.
        self._stream = _seed_stream(seed) if rng is None else None
        self.rnd = None
        if rng is None and self._stream is None:
            self.rnd = np.random.RandomState(seed)
        self._block: list[float] = self._stream.values if self._stream is not None else []
        self._next_in_block = 0

    def next(self) -> float:
        if self._rng is not None:
            value = float(self._rng.exponential(self.l))
        else:
            position = self._next_in_block
            if position == len(self._block):
                self._more()
                position = self._next_in_block
            self._next_in_block = position + 1
            value = self.l * self._block[position]
        if not self.integer:
            return value
        return max(int(value), 1)

    def _more(self) -> None:
        """Make the next draw available at ``self._block[self._next_in_block]``."""
        stream = self._stream
        if stream is not None:
            if stream.grow():
                return
            # The shared part is used up: a private generator, moved past it.
            self._stream = None
            self.rnd = np.random.RandomState(stream.seed)
            self.rnd.standard_exponential(size=len(stream.values))
            self._block = []
        # Private blocks grow (8, 16, ... 512): short runs draw little ahead.
        size = min(2 * len(self._block), _BLOCK) if self._block else 8
        assert self.rnd is not None
        self._block = self.rnd.standard_exponential(size=size).tolist()
        self._next_in_block = 0


class exponentialDistribution(exponential_distribution):  # noqa: N801 - YAFS name
    """YAFS3's deprecated name of :class:`exponential_distribution` (same draws); it warns
    with a ``FutureWarning`` as YAFS3 does."""

    def __init__(self, lambd: float, seed: int = 1, name: str = "", **kwargs: Any) -> None:
        warnings.warn("exponentialDistribution is YAFS3's deprecated name; use exponential_distribution",
                      FutureWarning, stacklevel=2)
        super().__init__(lambd, seed=seed, name=name, **kwargs)


class exponentialDistributionStartPoint(Distribution):  # noqa: N801 - YAFS name
    """``start`` first, then exponential times of mean ``lambd`` truncated to integers.

    As YAFS3: the draws come from numpy's global legacy generator (``numpy.random``) and,
    unlike :class:`exponential_distribution`, a draw below 1 gives 0. Pass ``rng`` (a
    ``numpy.random.Generator`` or ``RandomState``) to draw from it instead.

    Args:
        start: the first value.
        lambd: the mean of the following inter-event times.
        rng: a generator to draw from (default: numpy's global one, YAFS-compatible).
        name: a label.
    """

    def __init__(self, start: float, lambd: float, rng: Any = None, name: str = "") -> None:
        super().__init__(name)
        self.start = start
        self.lambd = lambd
        self.started = False
        self._rng = rng

    def next(self) -> float:
        if not self.started:
            self.started = True
            return self.start
        draw = np.random.exponential if self._rng is None else self._rng.exponential
        return int(draw(self.lambd))


class uniformDistribution(Distribution):  # noqa: N801 - YAFS name
    """Uniform integer inter-event times in ``[min, max]`` (inclusive).

    As YAFS3 the default draws from Python's global ``random`` (``random.randint``). For a
    stream of its own pass ``rng`` (a ``random.Random``) or ``seed`` (a private
    ``random.Random(seed)``).

    Args:
        min: lower bound.
        max: upper bound.
        seed: seed of a private generator (when ``rng`` is not given).
        rng: a ``random.Random`` to draw from.
        name: a label.
    """

    def __init__(
        self,
        min: int,  # noqa: A002 - YAFS keyword name
        max: int,  # noqa: A002 - YAFS keyword name
        seed: int | None = None,
        rng: random.Random | None = None,
        name: str = "",
    ) -> None:
        super().__init__(name)
        if max < min:
            raise ValueError(f"uniformDistribution: max ({max}) < min ({min})")
        self.min = min
        self.max = max
        if rng is None and seed is not None:
            rng = random.Random(seed)
        self._randint = rng.randint if rng is not None else random.randint

    def next(self) -> float:
        return self._randint(self.min, self.max)
