"""Eq. 1 and Eq. 4 as pure functions."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from yafs_safetail.edge.latency import copy_latency, copy_latency_s, target_latency_s


def test_eq1_hand_computed_example():
    # 100 kB in over min(8 Mbit/s, 4 Mbit/s), 2 kB out over min(10, 20) Mbit/s.
    parts = copy_latency(
        input_bytes=100_000,
        output_bytes=2_000,
        server_uplink_bps=10e6,
        server_downlink_bps=8e6,
        user_uplink_bps=4e6,
        user_downlink_bps=20e6,
        propagation_s=0.05,
        compute_s=0.4,
    )
    assert parts.input_upload_s == pytest.approx(0.2)
    assert parts.input_download_s == pytest.approx(0.2)
    assert parts.output_upload_s == pytest.approx(0.0016)
    assert parts.propagation_s == pytest.approx(0.1)
    assert parts.upload_s == pytest.approx(0.2016)
    assert parts.download_s == pytest.approx(0.2016)
    assert parts.total_s == pytest.approx(0.4 + 0.1 + 2 * 0.2 + 2 * 0.0016)


positive = st.floats(min_value=1e3, max_value=1e9, allow_nan=False)


@given(
    st.floats(min_value=0, max_value=1e7),
    st.floats(min_value=0, max_value=1e7),
    positive,
    positive,
    positive,
    positive,
    st.floats(min_value=0, max_value=5),
    st.floats(min_value=0, max_value=50),
)
def test_eq1_scalar_and_vector_forms_agree(i_b, o_b, su, sd, uu, ud, rho, comp):
    parts = copy_latency(i_b, o_b, su, sd, uu, ud, rho, comp)
    vector = copy_latency_s(np.array([i_b]), o_b, su, sd, uu, ud, rho, comp)
    assert vector[0] == pytest.approx(parts.total_s, rel=1e-12)
    assert parts.total_s == pytest.approx(
        parts.upload_s + parts.download_s + parts.propagation_s + parts.compute_s, rel=1e-12
    )


def test_eq1_slower_server_link_only_matters_when_it_is_the_bottleneck():
    fast_user = copy_latency(1e5, 1e3, 10e6, 10e6, 50e6, 50e6, 0.0, 0.0).total_s
    slow_server = copy_latency(1e5, 1e3, 1e6, 1e6, 50e6, 50e6, 0.0, 0.0).total_s
    assert slow_server == pytest.approx(10 * fast_user)
    user_bottleneck = copy_latency(1e5, 1e3, 100e6, 100e6, 10e6, 10e6, 0.0, 0.0).total_s
    assert user_bottleneck == pytest.approx(fast_user)


def test_eq4_uses_user_bandwidth_median_propagation_and_estimated_output():
    tau = target_latency_s(
        input_bytes=50_000,
        est_output_bytes=5_000,
        user_uplink_bps=20e6,
        user_downlink_bps=40e6,
        server_median_propagation_s=np.array([0.05, 0.7, 0.1, 0.5, 0.9]),
        median_compute_s=0.45,
    )
    expected = 2 * 0.02 + 2 * 0.5 + 0.45 + 2 * 0.001
    assert tau == pytest.approx(expected)


def test_eq4_vectorised_over_steps():
    rho = np.array([[0.1, 0.2, 0.3], [0.3, 0.3, 0.9]])
    tau = target_latency_s(np.array([0.0, 0.0]), 0.0, 1e6, 1e6, rho, 1.0)
    np.testing.assert_allclose(tau, [1.4, 1.6])
