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

import operator
import sys
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from yafs_safetail.edge.observation import Observation
from yafs_safetail.record import RequestRecord


class PolicyError(ValueError):
    """A bad policy, policy parameter or method name (one line naming it)."""


def raised_where(error: BaseException, policy_class: type) -> str:
    """``Type: message (file.py line N)``: the exception and the last line of the policy's own
    file it passed through (one line, where a traceback would be many)."""
    source = getattr(sys.modules.get(policy_class.__module__), "__file__", None)
    frames = traceback.extract_tb(error.__traceback__)
    own = [frame for frame in frames if source is not None and frame.filename == source] or frames[-1:]
    at = f" ({Path(own[-1].filename).name} line {own[-1].lineno})" if own else ""
    return f"{type(error).__name__}: {error}{at}"


def is_users(policy: object) -> bool:
    """Whether a policy's class comes from outside this package (a user's ``--method``)."""
    return not type(policy).__module__.startswith("yafs_safetail.")


def where_defined(policy_class: type) -> str:
    """``path/file.py:Class`` (or ``module:Class`` without a file), as ``--method`` names it."""
    source = getattr(sys.modules.get(policy_class.__module__), "__file__", None)
    return f"{source or policy_class.__module__}:{policy_class.__name__}"


def name_a_users_failure(policy: object, error: Exception, request: str) -> None:
    """Called where a policy's ``choose`` raised on ``request`` ("request 30 of its phase"): for
    a user's policy, raise one line naming its file, class, the request and the line of the
    user's file; for a built-in one return, so that the caller re-raises with the traceback this
    project's developers need.

    Raises:
        PolicyError: ``policy`` is a user's.
    """
    if not is_users(policy):
        return
    cls = type(policy)
    name = getattr(policy, "name", cls.__name__)
    raise PolicyError(f"{name} ({where_defined(cls)}): {cls.__name__}.choose() raised on {request}: "
                      f"{raised_where(error, cls)}") from None


#: How a policy can ask for its chosen servers' copies to be sent (``Policy.dispatch``):
#: ``"all"`` at once; ``"hedge"``, the first now and each next one if no reply came within the
#: policy's ``hedge_delay_s()`` (see :class:`HedgingPolicy`); ``"tied"``, all at once, the others
#: cancelled as soon as one starts running. Which of them a world can run is the world's to
#: say (its :class:`DispatchSupport`).
DISPATCH_MODES: tuple[str, ...] = ("all", "hedge", "tied")


@runtime_checkable
class HedgingPolicy(Protocol):
    """What a policy asking for ``dispatch = "hedge"`` adds."""

    def hedge_delay_s(self) -> float:
        """How long to wait for a reply before the next copy (inf: only after a refusal)."""
        ...


@dataclass(frozen=True)
class DispatchSupport:
    """A world's declaration of the dispatch modes it runs.

    Attributes:
        world: its name in messages (e.g. ``"the single-user world"``).
        modes: the modes it runs, from :data:`DISPATCH_MODES`.
        elsewhere: where the other modes run, for the refusal (empty: nowhere else).
    """

    world: str
    modes: tuple[str, ...]
    elsewhere: str = ""


def check_dispatch(policy: Policy, support: DispatchSupport) -> None:
    """The one check, made by each world before a policy's first request, that the world can
    send copies as ``policy`` asks.

    Raises:
        PolicyError: one line naming the method, its dispatch mode and the world.
    """
    mode = policy.dispatch
    if mode not in support.modes:
        needs = f"needs {support.elsewhere}" if support.elsewhere else "is not supported"
        runs = ", ".join(repr(m) for m in support.modes)
        raise PolicyError(f"{policy.name}: dispatch {mode!r} {needs}; {support.world} runs {runs}")
    if mode == "hedge" and not isinstance(policy, HedgingPolicy):
        raise PolicyError(f"{policy.name}: dispatch 'hedge' needs a hedge_delay_s() method")


def choice_problem(chosen: object, n_servers: int) -> tuple[tuple[int, ...], str]:
    """What ``choose`` returned as Python ints in its order, and what is wrong with it.

    Returns:
        ``(servers, "")`` for a valid choice: non-empty, distinct integers within 0..n-1
        (Python or NumPy integers, in a list, tuple or array); else ``((), problem)``, the
        problem in words a policy's author can act on.
    """
    if isinstance(chosen, str | bytes) or not hasattr(chosen, "__iter__"):
        return (), f"not a list of server indices such as [0, 2] (it is of type {type(chosen).__name__})"
    items = list(chosen)
    # A mask (one boolean per server) is a likely slip; Python's True would pass as index 1.
    if any(isinstance(i, bool | np.bool_) for i in items):
        return (), "a mask of booleans, not server indices (np.flatnonzero(mask) gives them)"
    try:
        # operator.index: integers of any kind, never a float or text that merely converts.
        servers = tuple(operator.index(i) for i in items)
    except TypeError:
        return (), "not server indices: each must be an integer"
    if not servers:
        return (), f"no server: choose at least one of 0..{n_servers - 1}"
    if min(servers) < 0 or max(servers) >= n_servers:
        outside = next(i for i in servers if not 0 <= i < n_servers)
        return (), f"server {outside} does not exist: the servers are 0..{n_servers - 1}"
    if len(set(servers)) != len(servers):
        twice = next(i for i in servers if servers.count(i) > 1)
        return (), f"server {twice} is chosen twice: each server gets at most one copy"
    return servers, ""


def checked_choice(chosen: Sequence[int], n_servers: int, name: str) -> tuple[int, ...]:
    """What ``choose`` returned as Python ints in its order (a hedge tries them in that order),
    or PolicyError naming the method, the choice and what is wrong (:func:`choice_problem`)."""
    # Every request of every method passes here: a valid tuple or list of Python ints (what the
    # baselines and most policies return) is accepted without choice_problem's fuller reading.
    if type(chosen) in (tuple, list) and all(type(i) is int for i in chosen):
        servers = tuple(chosen)
        if servers and len(set(servers)) == len(servers) and min(servers) >= 0 and max(servers) < n_servers:
            return servers
    servers, problem = choice_problem(chosen, n_servers)
    if problem:
        raise PolicyError(f"{name}: invalid subset {chosen!r} for {n_servers} servers: {problem}")
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
        dispatch: how the chosen servers get their copies, one of :data:`DISPATCH_MODES`
            (default ``"all"``, every method of the paper). A policy only asks; each world says
            which modes it runs and refuses the others before the first request
            (:func:`check_dispatch`). A class attribute; SafeTail sets it per instance.
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

    def feedback(self, outcome: RequestRecord) -> RequestRecord | None:
        """Called once per completed request, in completion order (optional).

        Returns:
            None to keep ``outcome`` as the request's record, or a replacement (e.g. with the
            ``reward`` a learner computed filled in).
        """
        return None
