"""The 2^n - 1 actions of §III and the non-empty server subsets they stand for.

Mapping: action ``a`` (0 <= a <= 2^n - 2) is the bitmask ``a + 1``; server ``i`` (0-based, the
edge model's server order) is in the subset iff bit ``i`` of ``a + 1`` is set. So for n = 3:
action 0 = (0,), 1 = (1,), 2 = (0, 1), 3 = (2,), 4 = (0, 2), 5 = (1, 2), 6 = (0, 1, 2).
The full set is always the last action, ``2^n - 2``.
"""

from __future__ import annotations

from collections.abc import Iterable
from functools import lru_cache

import numpy as np

MAX_SERVERS = 10
"""Largest n supported (paper assumption iii: fewer than 10 reachable servers)."""


def _check_n_servers(n_servers: int) -> int:
    if isinstance(n_servers, bool) or not isinstance(n_servers, int | np.integer):
        raise ValueError(f"n_servers must be an integer, got {n_servers!r}")
    n = int(n_servers)
    if not 1 <= n <= MAX_SERVERS:
        raise ValueError(f"n_servers must be in 1..{MAX_SERVERS}, got {n}")
    return n


def n_actions(n_servers: int) -> int:
    """Number of actions (non-empty subsets) for ``n_servers`` servers: 2^n - 1.

    Raises:
        ValueError: ``n_servers`` is not an integer in 1..10.
    """
    return (1 << _check_n_servers(n_servers)) - 1


@lru_cache(maxsize=MAX_SERVERS)
def _subset_table(n: int) -> tuple[tuple[int, ...], ...]:
    return tuple(
        tuple(i for i in range(n) if (mask >> i) & 1) for mask in range(1, 1 << n)
    )


@lru_cache(maxsize=MAX_SERVERS)
def subset_matrix(n_servers: int) -> np.ndarray:
    """Boolean matrix ``M[a, b]``: the subset of action ``b`` is contained in that of ``a``.

    Read-only; shape (2^n - 1, 2^n - 1). Used by the target vector.
    """
    n = _check_n_servers(n_servers)
    masks = np.arange(1, 1 << n, dtype=np.int64)
    matrix = (masks[None, :] & ~masks[:, None]) == 0
    matrix.setflags(write=False)
    return matrix


def subset_of(action_index: int, n_servers: int) -> tuple[int, ...]:
    """Server indices (ascending) of the subset that action ``action_index`` selects.

    Args:
        action_index: An action in 0..2^n - 2.
        n_servers: n, in 1..10.

    Returns:
        The non-empty tuple of 0-based server indices, ascending.

    Raises:
        ValueError: ``n_servers`` out of 1..10 or ``action_index`` not an integer in range.
    """
    n = _check_n_servers(n_servers)
    if isinstance(action_index, bool) or not isinstance(action_index, int | np.integer):
        raise ValueError(f"action_index must be an integer, got {action_index!r}")
    a = int(action_index)
    if not 0 <= a < (1 << n) - 1:
        raise ValueError(f"action_index must be in 0..{(1 << n) - 2} for n_servers={n}, got {a}")
    return _subset_table(n)[a]


def action_of(subset: Iterable[int], n_servers: int) -> int:
    """Action index of a non-empty subset of server indices (inverse of :func:`subset_of`).

    Args:
        subset: Distinct 0-based server indices, any order.
        n_servers: n, in 1..10.

    Returns:
        The action index in 0..2^n - 2.

    Raises:
        ValueError: empty subset, an index that is not an integer in 0..n-1, or a repeated index.
    """
    n = _check_n_servers(n_servers)
    mask = 0
    count = 0
    for server in subset:
        if isinstance(server, bool) or not isinstance(server, int | np.integer):
            raise ValueError(f"subset entries must be integer server indices, got {server!r}")
        i = int(server)
        if not 0 <= i < n:
            raise ValueError(f"server index {i} out of range 0..{n - 1}")
        if (mask >> i) & 1:
            raise ValueError(f"server index {i} repeated in subset")
        mask |= 1 << i
        count += 1
    if count == 0:
        raise ValueError("subset must be non-empty (the paper's actions exclude the empty set)")
    return mask - 1
