"""State encoding of ω^t (Definition 1)."""

from __future__ import annotations

import numpy as np
import pytest

from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.safetail.spaces import (
    StateScales,
    encode_state,
    state_dim,
    state_feature_names,
)


def make_observation(n: int = 3, gamma: tuple[float, ...] = (2.5,)) -> Observation:
    return Observation(
        server_uplink_bps=np.array([10e6, 20e6, 5e6][:n]),
        server_downlink_bps=np.array([2e6, 4e6, 8e6][:n]),
        server_memory_util=np.array([0.1, 0.2, 0.3][:n]),
        server_cpu_util=np.array([0.5, 0.6, 0.7][:n]),
        server_active_users=np.array([0, 2, 4][:n]),
        server_median_propagation_s=np.array([0.05, 0.5, 0.7][:n]),
        input_bytes=80e3,
        est_output_bytes=2e3,
        gamma=np.array(gamma),
        user_location=np.array([3.0, -4.0]),
        user_uplink_bps=10e6,
        user_downlink_bps=40e6,
        server_max_load=np.full(n, 4),
    )


def test_layout_and_normalisation() -> None:
    scales = StateScales(input_bytes=160e3, output_bytes=4e3, gamma=(5.0,), location=2.0)
    x = encode_state(make_observation(), scales)
    assert x.dtype == np.float32
    assert x.shape == (state_dim(3, 1, 2),) == (6 * 3 + 2 + 1 + 2 + 2,)
    expected = [
        0.5, 0.1, 0.1, 0.5, 0.0, 0.05,
        1.0, 0.2, 0.2, 0.6, 0.5, 0.5,
        0.25, 0.4, 0.3, 0.7, 1.0, 0.7,
        0.5, 0.5, 0.5,
        1.5, -2.0,
        0.5, 2.0,
    ]
    np.testing.assert_allclose(x, expected, rtol=1e-6)
    names = state_feature_names(3, 1, 2)
    assert len(names) == x.shape[0]
    assert names[:6] == [
        "server0_uplink_bps", "server0_downlink_bps", "server0_memory_util",
        "server0_cpu_util", "server0_active_users", "server0_median_propagation_s",
    ]
    assert names[18:] == [
        "input_bytes", "est_output_bytes", "gamma0", "location0", "location1",
        "user_uplink_bps", "user_downlink_bps",
    ]


def test_empty_gamma_and_new_array_each_call() -> None:
    scales = StateScales.for_use_case(1)
    obs = make_observation(gamma=())
    a = encode_state(obs, scales)
    b = encode_state(obs, scales)
    assert a.shape == (state_dim(3, 0, 2),)
    assert a is not b
    np.testing.assert_array_equal(a, b)


def test_gamma_length_mismatch_is_reported() -> None:
    with pytest.raises(ValueError, match="1 Γ entries but StateScales.gamma has 2"):
        encode_state(make_observation(), StateScales.for_use_case(3))


def test_use_case_defaults_follow_the_edge_gamma_columns() -> None:
    from yafs_safetail.edge.usecases import USE_CASES

    for number, use_case in USE_CASES.items():
        scales = StateScales.for_use_case(number)
        assert len(scales.gamma) == len(use_case.gamma_columns)
    assert StateScales.for_use_case(3).gamma == (160e3, 5.0)


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"input_bytes": 0.0, "output_bytes": 1.0}, "StateScales.input_bytes"),
        ({"input_bytes": 1.0, "output_bytes": 1.0, "bandwidth_bps": -1.0}, "bandwidth_bps"),
        ({"input_bytes": 1.0, "output_bytes": 1.0, "gamma": (1.0, float("nan"))}, r"gamma\[1\]"),
    ],
)
def test_scales_validation(kwargs: dict, fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment):
        StateScales(**kwargs)


def test_unknown_use_case() -> None:
    with pytest.raises(ValueError, match=r"use_case must be one of \[1, 2, 3\], got 4"):
        StateScales.for_use_case(4)
