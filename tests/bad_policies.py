"""Users' policies with the mistakes a run must catch at once (``--method tests/bad_policies.py:Name``).

Not a test module: the tests load its classes by file path, as a user's ``--method`` does.
"""

from __future__ import annotations

import numpy as np

from yafs_safetail.methods import Policy


class Empty(Policy):
    """No server at all."""

    def choose(self, observation):
        return []


class OutOfRange(Policy):
    def choose(self, observation):
        return [observation.n_servers]


class Twice(Policy):
    observes = False

    def choose(self, observation):
        return (1, 1)


class Mask(Policy):
    """One boolean per server instead of the chosen servers' indices."""

    def choose(self, observation):
        return observation.server_active_users < observation.server_max_load


class Text(Policy):
    observes = False

    def choose(self, observation):
        return "0"


class Raises(Policy):
    def choose(self, observation):
        return [int(observation.server_active_users[99])]


class Hedger(Policy):
    """Asks for hedged copies, which the single-user world does not run."""

    dispatch = "hedge"

    def hedge_delay_s(self):
        return 0.1

    def choose(self, observation):
        return (0,)


class Vandal(Policy):
    """Writes into every array of the observation it is given, then chooses well."""

    def choose(self, observation):
        for value in (observation.server_median_propagation_s, observation.server_active_users,
                      observation.server_uplink_bps, observation.gamma, observation.server_max_load):
            value[...] = 0
        return (0,)


class Later(Policy):
    """Fine on the first requests, then no server: found only when its simulation gets there."""

    def choose(self, observation):
        return [] if observation.step >= 20 else [int(np.argmin(observation.server_median_propagation_s))]


class RaisesLate(Policy):
    """Chooses well on its first requests, then fails on the 30th of a phase."""

    observes = False

    def __init__(self, n_servers, rng):
        super().__init__(n_servers, rng)
        self.calls = 0

    def choose(self, observation):
        self.calls += 1
        if self.calls == 30:
            raise RuntimeError("late bug")
        return (0,)
