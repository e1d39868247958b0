"""Eq. 5 (reward) and the §III training target vector built from it."""

from __future__ import annotations

import math

import numpy as np

from yafs_safetail.policy.actions import n_actions, subset_matrix


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
    if not (math.isfinite(latency_s) and latency_s >= 0.0):
        raise ValueError(f"latency_s must be finite and >= 0, got {latency_s!r}")
    if not (math.isfinite(target_s) and target_s > 0.0):
        raise ValueError(f"target_s must be finite and > 0, got {target_s!r}")
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


def target_vector(action_index: int, reward: float, n_servers: int) -> np.ndarray:
    """The §III training target V^t for one (action, reward) pair.

    * reward = 0: one-hot on ``action_index``.
    * reward < 0: with N = 2^n - 1, every action whose subset is contained in the chosen
      subset (the chosen action included) gets max(0, 1/N + reward); the remaining mass
      1 - Σ(those) is spread equally over all the other actions.

    Edge cases (the paper is silent):

    * The chosen subset is the full set: every action is one of its subsets, so no "other"
      entry exists. All entries then hold the same value and the remaining mass is spread
      equally over all of them, i.e. the vector is uniform, 1/N each.
    * The remaining mass can never be negative: for reward <= 0 each adjusted entry is at most
      1/N and there are at most N of them. Positive rewards (which Eq. 5 never produces) are
      rejected instead of being given a meaning.

    Args:
        action_index: The chosen action, 0..2^n - 2.
        reward: The Eq. 5 reward of that action, finite and <= 0.
        n_servers: n, 1..10.

    Returns:
        float64 array of shape (2^n - 1,), non-negative, summing to 1 (up to float rounding).

    Raises:
        ValueError: bad ``n_servers`` or ``action_index``, or a positive / non-finite reward.
    """
    n_total = n_actions(n_servers)
    if isinstance(action_index, bool) or not isinstance(action_index, int | np.integer):
        raise ValueError(f"action_index must be an integer, got {action_index!r}")
    if not 0 <= action_index < n_total:
        raise ValueError(
            f"action_index must be in 0..{n_total - 1} for n_servers={n_servers}, got {action_index}"
        )
    if not math.isfinite(reward) or reward > 0.0:
        raise ValueError(f"reward must be finite and <= 0 (Eq. 5), got {reward!r}")
    vector = np.empty(n_total, dtype=np.float64)
    if reward == 0.0:
        vector.fill(0.0)
        vector[action_index] = 1.0
        return vector
    contained = subset_matrix(n_servers)[action_index]
    n_contained = int(np.count_nonzero(contained))
    adjusted = max(0.0, 1.0 / n_total + reward)
    n_other = n_total - n_contained
    if n_other == 0:
        vector.fill(1.0 / n_total)
    else:
        vector.fill((1.0 - n_contained * adjusted) / n_other)
        vector[contained] = adjusted
    return vector
