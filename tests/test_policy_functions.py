"""Actions <-> subsets, Eq. 5 reward and the §III target vector."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from yafs_safetail.methods.safetail import action_of, n_actions, reward, subset_of, target_vector
from yafs_safetail.methods.safetail.spaces import membership_matrix

n_servers_st = st.integers(min_value=1, max_value=10)


@st.composite
def n_and_action(draw: st.DrawFn) -> tuple[int, int]:
    n = draw(n_servers_st)
    return n, draw(st.integers(min_value=0, max_value=(1 << n) - 2))


# --- actions -------------------------------------------------------------------------------


def test_documented_mapping_n3() -> None:
    expected = [(0,), (1,), (0, 1), (2,), (0, 2), (1, 2), (0, 1, 2)]
    assert [subset_of(a, 3) for a in range(7)] == expected
    assert n_actions(3) == 7
    assert action_of((2, 0), 3) == 4


@given(n_and_action())
def test_subset_action_roundtrip(case: tuple[int, int]) -> None:
    n, a = case
    subset = subset_of(a, n)
    assert len(subset) >= 1
    assert list(subset) == sorted(set(subset))
    assert all(0 <= i < n for i in subset)
    assert action_of(subset, n) == a
    assert action_of(reversed(subset), n) == a


@pytest.mark.parametrize("n", [1, 4, 10])
def test_mapping_is_a_bijection(n: int) -> None:
    subsets = {subset_of(a, n) for a in range(n_actions(n))}
    assert len(subsets) == (1 << n) - 1
    assert subset_of(n_actions(n) - 1, n) == tuple(range(n))


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        ((0, 0), "n_servers must be in 1..10"),
        ((0, 11), "n_servers must be in 1..10"),
        ((7, 3), "action_index must be in 0..6"),
        ((-1, 3), "action_index must be in 0..6"),
        ((1.0, 3), "action_index must be an integer"),
        ((True, 3), "action_index must be an integer"),
        ((0, 2.0), "n_servers must be an integer"),
    ],
)
def test_subset_of_rejects(args: tuple[object, object], fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        subset_of(*args)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("subset", "fragment"),
    [
        ((), "non-empty"),
        ((3,), "out of range 0..2"),
        ((-1,), "out of range"),
        ((1, 1), "repeated"),
        ((0.5,), "integer server indices"),
    ],
)
def test_action_of_rejects(subset: tuple[object, ...], fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        action_of(subset, 3)  # type: ignore[arg-type]


@pytest.mark.parametrize("n", [1, 3, 5, 10])
def test_membership_matrix_marks_each_actions_servers(n: int) -> None:
    matrix = membership_matrix(n)
    assert matrix.shape == (n_actions(n), n) and matrix.dtype == np.float32
    for a in range(n_actions(n)):
        assert tuple(np.flatnonzero(matrix[a]).tolist()) == subset_of(a, n)
    with pytest.raises(ValueError):
        matrix[0, 0] = 2.0


def test_numpy_integers_accepted() -> None:
    assert subset_of(np.int64(2), np.int32(3)) == (0, 1)
    assert action_of(np.array([0, 1]), 3) == 2


# --- reward (Eq. 5) ------------------------------------------------------------------------

latency_st = st.floats(min_value=0.0, max_value=100.0, allow_nan=False)
target_st = st.floats(min_value=1e-3, max_value=100.0, allow_nan=False)
delta_st = st.floats(min_value=1e-6, max_value=1.0, allow_nan=False)


@st.composite
def n_and_k(draw: st.DrawFn) -> tuple[int, int]:
    n = draw(n_servers_st)
    return n, draw(st.integers(min_value=1, max_value=n))


@given(latency_st, target_st, n_and_k(), delta_st)
def test_reward_upper_bound_zero(latency: float, target: float, nk: tuple[int, int], delta: float) -> None:
    n, k = nk
    assert reward(latency, target, k, n, delta) <= 0.0


@given(target_st, n_and_k(), delta_st)
def test_max_reward_when_latency_equals_target(target: float, nk: tuple[int, int], delta: float) -> None:
    n, k = nk
    assert reward(target, target, k, n, delta) == 0.0


@given(target_st, st.floats(min_value=1e-6, max_value=0.999), n_servers_st, delta_st)
def test_max_reward_below_target_with_one_server(
    target: float, fraction: float, n: int, delta: float
) -> None:
    assert reward(target * fraction, target, 1, n, delta) == 0.0


@given(target_st, st.floats(min_value=1e-3, max_value=50.0), n_servers_st, delta_st)
def test_max_reward_above_target_with_all_servers(
    target: float, excess: float, n: int, delta: float
) -> None:
    assert reward(target + excess, target, n, n, delta) == 0.0


@given(target_st, st.floats(min_value=1e-3, max_value=50.0), n_and_k(), delta_st)
def test_negative_above_target_with_room_to_add(
    target: float, excess: float, nk: tuple[int, int], delta: float
) -> None:
    n, k = nk
    if k == n:
        return
    r = reward(target + excess, target, k, n, delta)
    assert r < 0.0
    assert r == pytest.approx(-delta * math.exp(n - k), rel=1e-12)
    # Case 4 penalty grows with the redundancy still available and is at least δ·e.
    assert r <= -delta * math.e * (1 - 1e-12)


@given(target_st, st.floats(min_value=1e-6, max_value=0.999), n_and_k(), delta_st)
def test_negative_below_target_with_room_to_reduce(
    target: float, fraction: float, nk: tuple[int, int], delta: float
) -> None:
    n, k = nk
    if k == 1:
        return
    latency = target * fraction
    r = reward(latency, target, k, n, delta)
    assert -delta <= r < 0.0
    assert r == pytest.approx(-delta * math.exp(latency - target), rel=1e-12)


def test_case5_penalty_shrinks_with_margin() -> None:
    # As written: the further below τ, the smaller the penalty for redundancy.
    near = reward(0.99, 1.0, 3, 5, 0.003)
    far = reward(0.10, 1.0, 3, 5, 0.003)
    assert near < far < 0.0


def test_reward_table_values() -> None:
    assert reward(2.0, 1.0, 1, 5, 0.003) == pytest.approx(-0.003 * math.exp(4))
    assert reward(2.0, 1.0, 4, 5, 0.003) == pytest.approx(-0.003 * math.e)
    assert reward(0.5, 1.0, 2, 5, 0.003) == pytest.approx(-0.003 * math.exp(-0.5))


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        ((float("nan"), 1.0, 1, 5, 0.1), "latency_s"),
        ((-0.1, 1.0, 1, 5, 0.1), "latency_s"),
        ((0.1, 0.0, 1, 5, 0.1), "target_s"),
        ((0.1, float("inf"), 1, 5, 0.1), "target_s"),
        ((0.1, 1.0, 0, 5, 0.1), "n_selected"),
        ((0.1, 1.0, 6, 5, 0.1), "n_selected"),
        ((0.1, 1.0, 1, 5, 0.0), "delta"),
        ((0.1, 1.0, 1, 0, 0.1), "n_servers"),
    ],
)
def test_reward_rejects(args: tuple, fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        reward(*args)


# --- target vector -------------------------------------------------------------------------

reward_st = st.floats(min_value=-5.0, max_value=0.0, allow_nan=False)


@given(n_and_action(), reward_st)
def test_target_vector_is_a_distribution(case: tuple[int, int], r: float) -> None:
    n, a = case
    v = target_vector(a, r, n)
    assert v.shape == ((1 << n) - 1,)
    assert np.all(v >= 0.0)
    assert v.sum() == pytest.approx(1.0, abs=1e-9)


@given(n_and_action())
def test_target_vector_one_hot_at_zero_reward(case: tuple[int, int]) -> None:
    n, a = case
    v = target_vector(a, 0.0, n)
    expected = np.zeros((1 << n) - 1)
    expected[a] = 1.0
    np.testing.assert_array_equal(v, expected)


@given(n_and_action(), st.floats(min_value=-5.0, max_value=-1e-9))
def test_target_vector_subset_entries(case: tuple[int, int], r: float) -> None:
    n, a = case
    n_total = (1 << n) - 1
    v = target_vector(a, r, n)
    chosen = set(subset_of(a, n))
    inside = [b for b in range(n_total) if set(subset_of(b, n)) <= chosen]
    outside = [b for b in range(n_total) if b not in inside]
    assert a in inside
    if not outside:
        np.testing.assert_allclose(v, 1.0 / n_total)
        return
    adjusted = max(0.0, 1.0 / n_total + r)
    np.testing.assert_allclose(v[inside], adjusted)
    rest = (1.0 - len(inside) * adjusted) / len(outside)
    np.testing.assert_allclose(v[outside], rest)
    # A negative reward moves mass away from the chosen action and its subsets.
    assert v[a] < 1.0 / n_total <= v[outside[0]] + 1e-15


def test_target_vector_worked_example() -> None:
    # n = 2: actions (0,), (1,), (0, 1). Choose (0, 1)?  Full set -> uniform.
    np.testing.assert_allclose(target_vector(2, -0.1, 2), [1 / 3] * 3)
    # Choose (0,) with R = -0.1: entry 0 -> 1/3 - 0.1, the other two share the rest.
    v = target_vector(0, -0.1, 2)
    np.testing.assert_allclose(v, [1 / 3 - 0.1, (2 / 3 + 0.1) / 2, (2 / 3 + 0.1) / 2])
    # Large penalty clips at 0.
    np.testing.assert_allclose(target_vector(0, -1.0, 2), [0.0, 0.5, 0.5])


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        ((0, 0.1, 3), "reward must be finite and <= 0"),
        ((0, float("nan"), 3), "reward must be finite"),
        ((7, -0.1, 3), "action_index must be in 0..6"),
        ((0, -0.1, 11), "n_servers"),
    ],
)
def test_target_vector_rejects(args: tuple, fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        target_vector(*args)
