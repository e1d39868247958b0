"""Eq. 5: the reward of one request's outcome (the training target it becomes is in ``learner``)."""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np


def _check_latency_and_target(latency_s: float, target_s: float) -> None:
    if not (math.isfinite(latency_s) and latency_s >= 0.0):
        raise ValueError(f"latency_s must be finite and >= 0, got {latency_s!r}")
    if not (math.isfinite(target_s) and target_s > 0.0):
        raise ValueError(f"target_s must be finite and > 0, got {target_s!r}")


def reward(
    latency_s: float, target_s: float, n_selected: int, n_servers: int, delta: float
) -> float:
    """The paper's Eq. 5, all five cases exactly as written.

    With L_R = ``latency_s``, τ = ``target_s``, k = ``n_selected`` = |E_k| and n = ``n_servers``:

    1. L_R = τ                 -> 0
    2. L_R < τ and k = 1       -> 0
    3. L_R > τ and k = n       -> 0
    4. L_R > τ and k < n       -> -δ·e^(n - k)
    5. L_R < τ and k > 1       -> -δ·e^(L_R - τ)

    Case 1 is exact float equality. In case 5 the exponent is negative, so the penalty lies in
    (-δ, 0): it is largest (close to -δ) when L_R is just under τ and fades to 0 as the margin
    grows; it does not depend on how many servers (beyond one) were used. Case 4 is at most
    -δ·e, so missing the target always costs more than meeting it with redundancy. For n = 1
    only cases 1-3 can occur (every reward is 0).

    Args:
        latency_s: L_R, the achieved latency (Eq. 2), seconds, finite and >= 0.
        target_s: τ, the target latency (Eq. 4), seconds, finite and > 0.
        n_selected: |E_k|, the number of servers the action chose, 1..n.
        n_servers: n.
        delta: δ > 0.

    Returns:
        The reward, <= 0.

    Raises:
        ValueError: a non-finite or negative latency, a non-positive target, ``n_selected``
            outside 1..n, or a non-positive δ.
    """
    _check_latency_and_target(latency_s, target_s)
    if n_servers < 1:
        raise ValueError(f"n_servers must be >= 1, got {n_servers!r}")
    if not 1 <= n_selected <= n_servers:
        raise ValueError(f"n_selected must be in 1..{n_servers}, got {n_selected!r}")
    if not (math.isfinite(delta) and delta > 0.0):
        raise ValueError(f"delta must be finite and > 0, got {delta!r}")
    if latency_s == target_s:
        return 0.0
    if latency_s < target_s:
        if n_selected == 1:
            return 0.0
        return -delta * math.exp(latency_s - target_s)
    if n_selected == n_servers:
        return 0.0
    return -delta * math.exp(n_servers - n_selected)


def reward_no_free_miss(
    latency_s: float, target_s: float, n_selected: int, n_servers: int, delta: float
) -> float:
    """Eq. 5 with case 3 made a penalty: a miss with all n servers costs what a miss with n - 1
    costs (-δ·e). Not the paper's: the contention world's variant (docs/contention.md), where
    copies delay other requests and "all servers" must not be a free answer to a miss."""
    value = reward(latency_s, target_s, n_selected, n_servers, delta)
    if latency_s > target_s and n_selected == n_servers and n_servers > 1:
        return -delta * math.e
    return value


#: The latency-cost reward's price of a copy per job already on its server, in units of
#: −log(L_R / τ) (0.02: about 2% of the latency per job). Chosen, not derived: 0.01 was the best
#: of 0.003, 0.01, 0.03 and 0.1 on the use-case-1 load sweep with seed 0 in an earlier form of
#: this reward, and of 0.01 and 0.02 in this form on seeds 0-6; once tied requests kept at least
#: two copies (``policy.TIED_MIN_COPIES``), 0.02 was the best of 0.01, 0.02 and 0.03 on seeds
#: 0-6, then judged on the fresh seeds 43-54 (docs/deviations.md D13).
LOAD_PRICE = 0.02


def latency_score(latency_s: float, target_s: float) -> float:
    """-log(L_R / τ): the part of the latency-cost reward that the ``"value"`` network learns.

    Higher is better; 0 when the request just meets τ. On a log scale so that a queue's long
    latencies do not swamp the fit.

    Args:
        latency_s: L_R, seconds, finite and >= 0.
        target_s: τ, seconds, finite and > 0.
    """
    _check_latency_and_target(latency_s, target_s)
    # At least a sliver above 0: a request answered at once would take log(0).
    return -math.log(max(latency_s / target_s, 1e-6))


_Jobs = TypeVar("_Jobs", float, np.ndarray)


def copy_price(jobs_on_chosen: _Jobs) -> _Jobs:
    """LOAD_PRICE · Σ ℓ_i: what a request's copies cost the others, known at dispatch.

    A copy joining a server that runs ℓ_i jobs slows each of them (processor sharing) or waits
    behind them, so it is priced by ℓ_i: copies to idle servers are free, copies to busy ones
    are not, whatever the load the run was set to.

    Args:
        jobs_on_chosen: Σ ℓ_i over the servers an action chose, as observed at dispatch (>= 0),
            or an array of them, one per action (the policy prices every action at once).
    """
    return LOAD_PRICE * jobs_on_chosen


def reward_latency_cost(latency_s: float, target_s: float, jobs_on_chosen: int) -> float:
    """-log(L_R / τ) - LOAD_PRICE · Σ ℓ_i over the chosen servers: not the paper's.

    What the ``"value"`` learner's choices maximise (the contention world, docs/deviations.md
    D13): the request's latency in units of its target (:func:`latency_score`, the part the
    network predicts per action) less the price of its copies (:func:`copy_price`, which the
    policy knows exactly at dispatch and adds to each action's prediction instead of learning
    it). Positive when the request beats τ by more than its copies cost.

    Args:
        latency_s: L_R, seconds, finite and >= 0.
        target_s: τ, seconds, finite and > 0.
        jobs_on_chosen: Σ ℓ_i over the servers the action chose, as observed at dispatch.
    """
    if jobs_on_chosen < 0:
        raise ValueError(f"jobs_on_chosen must be >= 0, got {jobs_on_chosen!r}")
    return latency_score(latency_s, target_s) - copy_price(jobs_on_chosen)


def priced_reward(base: float, energy_j: float, replied: bool, energy_price_per_j: float = 0.0,
                  failure_penalty: float = 0.0) -> float:
    """A reward less the request's energy and failure prices: not the paper's (D15).

    ``base - energy_price_per_j * energy_j - failure_penalty * (not replied)``. With both prices
    0 it returns ``base`` itself (Eq. 5 exactly, whatever ``energy_j`` is).

    Args:
        base: the reward before the prices (Eq. 5, or the latency score).
        energy_j: what the request's copies cost: servers and the device's radio, joules.
        replied: whether the request ended with a reply within the time-out.
        energy_price_per_j: reward units per joule, >= 0.
        failure_penalty: reward units for a request that ended without a reply, >= 0.
    """
    if energy_price_per_j < 0 or failure_penalty < 0:
        raise ValueError(f"prices must be >= 0, got {energy_price_per_j!r} and {failure_penalty!r}")
    value = base
    if energy_price_per_j:
        if not math.isfinite(energy_j):
            raise ValueError(f"energy_j must be finite to be priced, got {energy_j!r}")
        value -= energy_price_per_j * energy_j
    if failure_penalty and not replied:
        value -= failure_penalty
    return value


def priced_latency_score(latency_s: float, target_s: float, energy_j: float, replied: bool,
                         energy_price_per_j: float = 0.0, failure_penalty: float = 0.0) -> float:
    """What the ``"value"`` network regresses for one request: :func:`latency_score` less the
    D15 prices, not the paper's.

    ``-log(L_R / τ) - energy_price_per_j * energy_j - failure_penalty * (not replied)``. Unlike
    :func:`copy_price`, known at dispatch and subtracted at choice time, a request's energy and
    whether it got a reply are known only once it ends, so the network learns them with its
    latency, per action. With both prices 0 it is the latency score itself (the contention
    world's SafeTail-CA, D13).

    Args:
        latency_s: L_R, seconds, finite and >= 0.
        target_s: τ, seconds, finite and > 0.
        energy_j: what the request's copies cost: servers and the device's radio, joules.
        replied: whether the request ended with a reply within the time-out.
        energy_price_per_j: score units per joule, >= 0.
        failure_penalty: score units for a request that ended without a reply, >= 0.
    """
    return priced_reward(latency_score(latency_s, target_s), energy_j, replied, energy_price_per_j,
                         failure_penalty)


#: The Eq. 5-shaped rewards a SafeTail policy can be trained with, by name (``"paper"`` = Eq. 5).
REWARDS = {"paper": reward, "no-free-miss": reward_no_free_miss}
#: Every reward name: those of :data:`REWARDS` and ``"latency-cost"``
#: (:func:`reward_latency_cost`, for the ``"value"`` objective only).
REWARD_NAMES = (*REWARDS, "latency-cost")
