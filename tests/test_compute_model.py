"""Compute model: shipped regressors' fit, NumPy == Keras, σ_k noise, seeded training."""

from __future__ import annotations

import json

import numpy as np
import pytest

from yafs_safetail.edge import published as pub
from yafs_safetail.edge.compute import (
    DEFAULT_MODELS_DIR,
    LATENCY_FLOOR_S,
    MODEL_INPUTS,
    ComputeModel,
    fit_metrics,
    split_rows,
    train_compute_models,
    train_regressor,
)
from yafs_safetail.edge.traces import DEFAULT_TRACE_DIR, ComputeTrace, TraceError, load_compute

# Held-out R² each shipped regressor must reach (README §7).
MIN_HELD_OUT_R2 = {1: 0.85, 2: 0.99, 3: 0.99}


@pytest.fixture(scope="module")
def compute_traces() -> dict[int, ComputeTrace]:
    return {uc: load_compute(DEFAULT_TRACE_DIR / f"compute_uc{uc}.csv", uc) for uc in pub.USE_CASES}


def _meta(use_case: int) -> dict:
    return json.loads((DEFAULT_MODELS_DIR / f"compute_uc{use_case}.json").read_text())


@pytest.mark.parametrize("use_case", pub.USE_CASES)
def test_shipped_regressor_fits_held_out_rows(use_case, compute_traces):
    trace = compute_traces[use_case]
    model = ComputeModel.load(use_case)
    assert model.inputs == MODEL_INPUTS[use_case]
    meta = _meta(use_case)
    _, test = split_rows(len(trace.frame), meta["seed"])
    prediction = model.predict_s(trace.gamma_matrix()[test], trace.n_processes[test])
    fit = fit_metrics(trace.latency_s[test], prediction)
    assert fit["r2"] >= MIN_HELD_OUT_R2[use_case]
    assert fit["r2"] == pytest.approx(meta["fit"]["r2"], abs=1e-9)
    assert fit["mae_s"] == pytest.approx(meta["fit"]["mae_s"], rel=1e-6)


@pytest.mark.parametrize("use_case", pub.USE_CASES)
def test_regressor_learned_the_slowdown(use_case, compute_traces):
    """ŷ(median Γ, k) / ŷ(median Γ, 1) follows s_k of README §4.1 within 10 %."""
    model = ComputeModel.load(use_case)
    gamma = np.median(compute_traces[use_case].gamma_matrix(), axis=0)
    k = np.arange(1, pub.MAX_PROCESSES + 1)
    prediction = model.predict_s(gamma if gamma.size else None, k)
    assert np.all(np.diff(prediction) > 0)
    np.testing.assert_allclose(prediction / prediction[0], pub.slowdown_factors(use_case), rtol=0.10)


@pytest.mark.parametrize("use_case", pub.USE_CASES)
def test_numpy_forward_pass_equals_keras(use_case, compute_traces):
    keras = pytest.importorskip("keras")
    trace = compute_traces[use_case]
    rows = np.random.default_rng(0).choice(len(trace.frame), size=400, replace=False)
    features = np.column_stack([trace.gamma_matrix()[rows], trace.n_processes[rows]]).astype(np.float32)
    keras_model = keras.saving.load_model(DEFAULT_MODELS_DIR / f"compute_uc{use_case}.keras")
    expected = np.asarray(keras_model.predict(features, verbose=0)).ravel()
    got = ComputeModel.load(use_case).predict_s(features[:, :-1], features[:, -1])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-5)


@pytest.mark.parametrize("use_case", pub.USE_CASES)
def test_noise_has_published_sigma_per_k(use_case):
    model = ComputeModel.load(use_case)
    rng = np.random.default_rng(11)
    n = 40_000
    for k in range(1, pub.MAX_PROCESSES + 1):
        prediction = np.full(n, 1.0)
        sample = model.sample_s(prediction, np.full(n, k), rng.standard_normal(n))
        sigma = pub.SIGMA_S[use_case][k - 1]
        assert np.std(sample - prediction) == pytest.approx(sigma, rel=0.03)
        assert abs(np.mean(sample - prediction)) < 4 * sigma / np.sqrt(n)


def test_sample_uses_caller_draws_and_clips_at_floor():
    model = ComputeModel.load(2)
    prediction = np.array([0.7, 0.7, 0.01])
    k = np.array([1, 5, 5])
    z = np.array([1.0, -2.0, -10.0])
    sample = model.sample_s(prediction, k, z)
    assert sample[0] == pytest.approx(0.7 + pub.SIGMA_S[2][0])
    assert sample[1] == pytest.approx(0.7 - 2 * pub.SIGMA_S[2][4])
    assert sample[2] == LATENCY_FLOOR_S
    np.testing.assert_array_equal(model.sample_s(prediction, k, z), sample)


def test_sigma_source_trace_uses_residual_std():
    model = ComputeModel.load(1, sigma_source="trace")
    np.testing.assert_allclose(model.sigma_s(np.arange(1, 6)), _meta(1)["trace_sigma_s"])
    # UC1's trace spread is far above the published σ_k (README §4.5).
    assert model.sigma_s(1) > 10 * pub.SIGMA_S[1][0]


def test_predict_broadcasts_and_validates():
    model = ComputeModel.load(3)
    gamma = np.array([96_044.0, 3.0])
    one_row = model.predict_s(gamma, np.arange(1, 6))
    many = model.predict_s(np.tile(gamma, (5, 1)), np.arange(1, 6))
    np.testing.assert_array_equal(one_row, many)
    assert model.predict_s(gamma, 2).shape == (1,)
    with pytest.raises(ValueError, match="gamma: shape"):
        model.predict_s(np.ones((3, 1)), np.ones(3))
    with pytest.raises(ValueError, match="n_processes"):
        model.sigma_s(np.array([0, 1]))
    assert ComputeModel.load(1).predict_s(None, np.array([1, 2])).shape == (2,)


def test_load_errors(tmp_path):
    with pytest.raises(TraceError, match="compute_uc1.npz: compute model file not found"):
        ComputeModel.load(1, tmp_path)
    with pytest.raises(ValueError, match="use_case"):
        ComputeModel.load(7)
    with pytest.raises(ValueError, match="sigma_source"):
        ComputeModel.load(1, sigma_source="guess")


def _small_trace(compute_traces: dict[int, ComputeTrace]) -> ComputeTrace:
    frame = compute_traces[3].frame
    small = frame.groupby("n_processes").head(60).reset_index(drop=True)
    return ComputeTrace(3, small, compute_traces[3].source)


def test_training_is_seeded(compute_traces):
    pytest.importorskip("keras")
    trace = _small_trace(compute_traces)
    model_a, meta_a = train_regressor(trace, seed=5, epochs=2)
    model_b, meta_b = train_regressor(trace, seed=5, epochs=2)
    model_c, _ = train_regressor(trace, seed=6, epochs=2)
    weights_a, weights_b, weights_c = (m.get_weights() for m in (model_a, model_b, model_c))
    for a, b in zip(weights_a, weights_b, strict=True):
        np.testing.assert_array_equal(a, b)
    assert any(not np.array_equal(a, c) for a, c in zip(weights_a, weights_c, strict=True))
    assert meta_a["fit"] == meta_b["fit"]
    assert meta_a["inputs"] == ["file_bytes", "duration_s", "n_processes"]


@pytest.mark.slow
def test_full_retraining_reproduces_shipped_models(tmp_path, compute_traces):
    pytest.importorskip("keras")
    train_compute_models(DEFAULT_TRACE_DIR, tmp_path, seed=2024)
    for use_case, trace in compute_traces.items():
        shipped = ComputeModel.load(use_case)
        fresh = ComputeModel.load(use_case, tmp_path)
        np.testing.assert_allclose(
            fresh.predict_s(trace.gamma_matrix(), trace.n_processes),
            shipped.predict_s(trace.gamma_matrix(), trace.n_processes),
            atol=1e-3,
        )


@pytest.mark.parametrize("damage", ["truncate", "garbage", "json"])
def test_a_damaged_model_file_is_one_line(tmp_path, damage):
    import shutil

    from yafs_safetail.edge.compute import ComputeModel

    models = tmp_path / "models"
    shutil.copytree(DEFAULT_TRACE_DIR / "models", models)
    npz, meta = models / "compute_uc1.npz", models / "compute_uc1.json"
    if damage == "truncate":
        npz.write_bytes(npz.read_bytes()[: npz.stat().st_size // 2])
    elif damage == "garbage":
        npz.write_bytes(b"not a zip file at all")
    else:
        meta.write_text("{\"inputs\": ")
    target = meta if damage == "json" else npz
    with pytest.raises(TraceError) as raised:
        ComputeModel.load(1, models)
    message = str(raised.value)
    assert message.startswith(str(target)) and "\n" not in message
