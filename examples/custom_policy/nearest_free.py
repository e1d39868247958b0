"""A policy of your own in ten lines: the nearest server that still has room.

    python experiments/run_usecase.py --uc 1 --method examples/custom_policy/nearest_free.py:NearestFree
"""

import numpy as np

from yafs_safetail.methods import Policy


class NearestFree(Policy):
    """One copy to the server with the lowest median propagation among those below their load
    limit (the nearest one when all are full)."""

    def choose(self, observation):
        full = observation.server_active_users >= observation.server_max_load
        # Full servers sort after every free one; among each group, nearest first.
        return np.lexsort((observation.server_median_propagation_s, full))[:1]
