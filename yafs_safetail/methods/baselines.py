"""The paper's baselines (§V-B) as policies: Oracle, Rand-x, MinLoad-x, MinProp-x.

MinLoad-x and MinProp-x have two readings (docs/calibration.md rule 5): the paper's text, the x
best of all n servers, and the original code's, the x best of a few servers drawn at random for
each request (``candidates``).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from yafs_safetail.defaults import BASELINE_READINGS, ORIGINAL_CODE_CANDIDATES
from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.policy import Policy, PolicyError


def _check_x(x: int, n: int, family: str) -> int:
    if isinstance(x, bool) or not isinstance(x, int | np.integer) or not 1 <= x <= n:
        raise PolicyError(f"{family}-x: x must be an integer in 1..{n} (the number of servers), got {x!r}")
    return int(x)


class Oracle(Policy):
    """Every request to all n servers (§V-B i): the per-request lower bound on latency in the
    paper's world, where copies do not cost each other anything."""

    observes: ClassVar[bool] = False

    def __init__(self, n_servers: int, rng: np.random.Generator) -> None:
        self.name = "Oracle"
        super().__init__(n_servers, rng)
        self._all = tuple(range(self.n_servers))

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        return self._all


class RandX(Policy):
    """x servers drawn uniformly without replacement per request (§V-B ii)."""

    observes: ClassVar[bool] = False

    def __init__(self, n_servers: int, rng: np.random.Generator, x: int) -> None:
        self.x = _check_x(x, n_servers, "Rand")
        self.name = f"Rand-{self.x}"
        super().__init__(n_servers, rng)

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        return tuple(self.rng.choice(self.n_servers, size=self.x, replace=False).tolist())


def candidates_of(reading: str, x: int, n_servers: int) -> int | None:
    """How many servers a MinLoad-x or MinProp-x of ``reading`` draws before sorting: None for
    the paper's text (all of them, no draw); the original code's three (x when x > 3, at most n).

    Raises:
        PolicyError: an unknown reading.
    """
    if reading not in BASELINE_READINGS:
        raise PolicyError(f"baseline reading {reading!r}: expected one of {', '.join(BASELINE_READINGS)}")
    if reading == "paper-text":
        return None
    return min(max(ORIGINAL_CODE_CANDIDATES, x), n_servers)


class MinLoadX(Policy):
    """The x servers with the fewest active users ℓ_i.

    ``candidates`` None (the paper's text, §V-B iv): of all n servers, ties broken at random.
    ``candidates`` k (the original code's reading): k distinct servers drawn uniformly for each
    request, sorted stably by load (ties keep the drawn order), the first x.
    """

    def __init__(self, n_servers: int, rng: np.random.Generator, x: int,
                 candidates: int | None = None) -> None:
        self.x = _check_x(x, n_servers, "MinLoad")
        self.name = f"MinLoad-{self.x}"
        super().__init__(n_servers, rng)
        self.candidates = candidates

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None
        load = observation.server_active_users
        if self.candidates is not None:
            drawn = self.rng.choice(self.n_servers, size=self.candidates, replace=False)
            return tuple(drawn[np.argsort(load[drawn], kind="stable")][: self.x].tolist())
        order = np.lexsort((self.rng.random(self.n_servers), load))  # ties broken at random
        return tuple(order[: self.x].tolist())



class LeastLoadedTwo(MinLoadX):
    """The two servers with the fewest active users among all n, whatever the baseline reading:
    the strongest simple policy, which the scoring suite (``yafs-safetail score``) sets beside a
    user's as a user's policy is given (``yafs_safetail.methods.baselines:LeastLoadedTwo``)."""

    def __init__(self, n_servers: int, rng: np.random.Generator) -> None:
        super().__init__(n_servers, rng, 2)
        self.name = "LeastLoaded-2"

class MinPropX(Policy):
    """The x servers with the lowest median propagation latency ρ^μ_i.

    ``candidates`` None (the paper's text, §V-B iii): of all n servers, ties by index; ρ^μ_i is
    a property of the topology, so the subset is computed from the first observation and kept.
    ``candidates`` k (the original code's reading): k distinct servers drawn uniformly for each
    request, sorted stably by the median propagation the observation shows, the first x.
    """

    def __init__(self, n_servers: int, rng: np.random.Generator, x: int,
                 candidates: int | None = None) -> None:
        self.x = _check_x(x, n_servers, "MinProp")
        self.name = f"MinProp-{self.x}"
        super().__init__(n_servers, rng)
        self.candidates = candidates
        self._subset: tuple[int, ...] | None = None

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None or self._subset is not None
        if self.candidates is not None:
            assert observation is not None
            drawn = self.rng.choice(self.n_servers, size=self.candidates, replace=False)
            propagation = observation.server_median_propagation_s
            return tuple(drawn[np.argsort(propagation[drawn], kind="stable")][: self.x].tolist())
        if self._subset is None:
            assert observation is not None
            order = np.argsort(observation.server_median_propagation_s, kind="stable")
            self._subset = tuple(order[: self.x].tolist())
        return self._subset
