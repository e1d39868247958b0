"""A policy of your own in ten lines: the nearest server with room, and a second copy when it is busy.

    yafs-safetail run --uc 1 --method examples/custom_policy/nearest_free.py:NearestFree
"""

import numpy as np

from yafs_safetail.methods import Policy


class NearestFree(Policy):
    """One copy to the nearest server below its load limit (lowest median propagation); when
    that server is busy (it runs more users than the least loaded server with room), a second
    copy to the least loaded one (the nearest of them on a tie).

    Unlike any baseline it weighs distance and load together, and sends one or two copies
    depending on the load it sees: MinProp-x reads distance only, MinLoad-x load only."""

    def choose(self, observation):
        active = observation.server_active_users
        full = active >= observation.server_max_load
        near = observation.server_median_propagation_s
        nearest = np.lexsort((near, full))[0]  # servers with room first, then nearest first
        idlest = np.lexsort((near, active, full))[0]  # ... then least loaded, then nearest
        return [nearest, idlest] if active[nearest] > active[idlest] else [nearest]
