"""What decides where a request's copies go: the :class:`Policy` every method implements.

A policy is a plain object. For each request it gets the state ω^t (an
:class:`~yafs_safetail.edge.observation.Observation`, the same one the Gymnasium environment
returns) and answers with the server indices to send one copy each to; when the request has
completed it gets the :class:`~yafs_safetail.record.RequestRecord` (latency, refusals, the winning
copy's Eq. 1 parts) as feedback. It never sees the simulator: ``sim.selection.PolicySelection``
drives any policy inside YAFS, and ``sim.env`` exposes the same loop to Gymnasium agents.

A new policy in a few lines::

    import numpy as np
    from yafs_safetail.methods import Policy

    class NearestFree(Policy):
        def choose(self, observation):
            full = observation.server_active_users >= observation.server_max_load
            return np.lexsort((observation.server_median_propagation_s, full))[:1]
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from yafs_safetail.edge.observation import Observation
from yafs_safetail.record import RequestRecord


class PolicyError(ValueError):
    """A bad policy, policy parameter or method name (one line naming it)."""


def checked_choice(chosen: Sequence[int], n_servers: int, name: str) -> tuple[int, ...]:
    """What ``choose`` returned as Python ints in its order (a hedge tries them in that order),
    or PolicyError naming the method and the choice: non-empty, distinct, within 0..n-1."""
    try:
        servers = tuple(int(i) for i in chosen)
    except (TypeError, ValueError):
        raise PolicyError(f"{name}: choose() must return server indices, got {chosen!r}") from None
    if not servers or len(set(servers)) != len(servers) or min(servers) < 0 or max(servers) >= n_servers:
        raise PolicyError(f"{name}: invalid subset {chosen!r} for {n_servers} servers")
    return servers


class Policy:
    """Base class of every method: SafeTail, the baselines and a user's own.

    Args:
        n_servers: n, the number of edge servers (indices 0..n-1 in the topology's order).
        rng: the method's own generator; draw every random number from it (same seed, same
            choices; other methods' draws are unaffected).

    Attributes:
        name: the method's name in results (default: the class name).
        observes: False for a policy that never reads ω^t: its :meth:`choose` then gets None,
            which saves building the state for every request.
        dispatch: how the chosen servers get their copies: ``"all"`` at once (every method of
            the paper); ``"hedge"``, the first now and each next one if no reply came within
            :meth:`hedge_delay_s`; ``"tied"``, all at once, the others cancelled as soon as one
            starts running. The last two exist only in the contention world
            (``yafs_safetail.contention``), where copies cost other requests something. A class
            attribute; SafeTail sets it per instance.
    """

    name: str = ""
    observes: ClassVar[bool] = True
    dispatch: str = "all"

    def __init__(self, n_servers: int, rng: np.random.Generator) -> None:
        self.n_servers = int(n_servers)
        self.rng = rng
        if not self.name:
            self.name = type(self).__name__

    def choose(self, observation: Observation | None) -> Sequence[int]:
        """The server indices (0..n-1, non-empty, no repeats) to send this request to.

        Args:
            observation: ω^t when the request is issued, or None when ``observes`` is False.
        """
        raise NotImplementedError(f"{type(self).__name__} must implement choose(observation)")

    def hedge_delay_s(self) -> float:
        """For ``dispatch = "hedge"``: how long to wait for a reply before the next copy."""
        raise NotImplementedError(f"{type(self).__name__} does not hedge")

    def feedback(self, outcome: RequestRecord) -> RequestRecord | None:
        """Called once per completed request, in completion order (optional).

        Returns:
            None to keep ``outcome`` as the request's record, or a replacement (e.g. with the
            ``reward`` a learner computed filled in).
        """
        return None
