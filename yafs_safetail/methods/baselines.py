"""The paper's baselines (§V-B) as policies: Oracle, Rand-x, MinLoad-x, MinProp-x."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

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


class MinLoadX(Policy):
    """The x servers with the fewest active users ℓ_i; ties broken at random (§V-B iv)."""

    def __init__(self, n_servers: int, rng: np.random.Generator, x: int) -> None:
        self.x = _check_x(x, n_servers, "MinLoad")
        self.name = f"MinLoad-{self.x}"
        super().__init__(n_servers, rng)

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None
        load = observation.server_active_users
        order = np.lexsort((self.rng.random(self.n_servers), load))  # ties broken at random
        return tuple(order[: self.x].tolist())


class MinPropX(Policy):
    """The x servers with the lowest median propagation latency ρ^μ_i; ties by index (§V-B iii).

    ρ^μ_i is a property of the topology, so the subset is computed from the first observation
    and kept.
    """

    def __init__(self, n_servers: int, rng: np.random.Generator, x: int) -> None:
        self.x = _check_x(x, n_servers, "MinProp")
        self.name = f"MinProp-{self.x}"
        super().__init__(n_servers, rng)
        self._subset: tuple[int, ...] | None = None

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        if self._subset is None:
            assert observation is not None
            order = np.argsort(observation.server_median_propagation_s, kind="stable")
            self._subset = tuple(order[: self.x].tolist())
        return self._subset
