"""Each world declares the dispatch modes it runs; a policy asking for another is refused once,
by ``methods.policy.check_dispatch``, with one line naming the method and the world."""

from __future__ import annotations

import math

import numpy as np
import pytest

from yafs_safetail.contention import run as contention_run
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.methods.hedging import Hedge, Tied
from yafs_safetail.methods.policy import DISPATCH_MODES, Policy, PolicyError, check_dispatch
from yafs_safetail.sim import selection


class FirstServer(Policy):
    observes = False

    def choose(self, observation):
        return (0,)


class HedgeWithoutDelay(FirstServer):
    dispatch = "hedge"


class BestEffort(FirstServer):
    dispatch = "best-effort"


def make(cls):
    return cls(5, np.random.default_rng(0))


def test_each_world_declares_its_modes():
    assert selection.DISPATCH.modes == ("all",)
    assert contention_run.DISPATCH.modes == DISPATCH_MODES
    for policy in (make(FirstServer), make(Hedge), make(Tied)):
        check_dispatch(policy, contention_run.DISPATCH)  # the contention world runs them all
    check_dispatch(make(FirstServer), selection.DISPATCH)


def test_the_single_user_world_names_the_world_that_runs_a_mode():
    with pytest.raises(PolicyError) as refused:
        check_dispatch(make(Tied), selection.DISPATCH)
    message = str(refused.value)
    assert message == ("Tied: dispatch 'tied' needs the contention world (yafs-safetail sweep); "
                       "the single-user world runs 'all'")


def test_an_unknown_mode_or_a_hedge_without_its_delay_is_refused_by_the_contention_world():
    with pytest.raises(PolicyError, match="^BestEffort: dispatch 'best-effort' is not supported; "
                                          "the contention world runs 'all', 'hedge', 'tied'$"):
        check_dispatch(make(BestEffort), contention_run.DISPATCH)
    with pytest.raises(PolicyError, match=r"^HedgeWithoutDelay: dispatch 'hedge' needs a hedge_delay_s\(\) method$"):
        check_dispatch(make(HedgeWithoutDelay), contention_run.DISPATCH)


def test_the_contention_world_checks_before_its_first_request():
    world = ContentionWorld(ContentionConfig(n_requests=10, users=1))
    with pytest.raises(PolicyError, match="dispatch 'hedge' needs a hedge_delay_s"):
        contention_run.run_policy(world, make(HedgeWithoutDelay))
    hedge = contention_run.PolicyDispatcher(world, make(Hedge))
    assert hedge.mode == "hedge" and hedge.hedge_delay_s() == math.inf  # no latencies seen yet
