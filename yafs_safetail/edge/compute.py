"""The paper's compute model: an MLP regressor per use case plus Gaussian noise N(ŷ, σ_k).

Paper §V-A: per use case an MLP maps the selected input traits Γ (and the number of parallel
processes k on the server) to compute latency ŷ; the simulated latency is ŷ + N(0, σ_k).

* Training (Keras, TensorFlow imported lazily) happens once, in ``traces/generate.py``; the
  models ship in ``traces/models/`` as ``compute_uc{n}.keras`` with input standardisation and
  output scaling inside the model, plus ``.npz`` (the same weights as arrays) and ``.json``
  (inputs, seed, held-out fit, residual std per k).
* Simulation uses :class:`ComputeModel`, a NumPy forward pass over the ``.npz`` weights:
  vectorised over any number of (request, k) pairs and free of TensorFlow.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal

import numpy as np

from yafs_safetail.edge import published as pub
from yafs_safetail.edge.traces import (
    DEFAULT_TRACE_DIR,
    GAMMA_COLUMNS,
    ComputeTrace,
    TraceError,
    load_compute,
)

DEFAULT_MODELS_DIR = DEFAULT_TRACE_DIR / "models"

MODEL_INPUTS: Mapping[int, tuple[str, ...]] = MappingProxyType(
    {uc: (*GAMMA_COLUMNS[uc], "n_processes") for uc in pub.USE_CASES}
)
"""Regressor inputs per use case, in column order: Γ then n_processes."""

HIDDEN_UNITS = (32, 32)
"""Hidden layer widths (the paper does not publish the regressor's shape)."""
EPOCHS = 60
BATCH_SIZE = 128
LEARNING_RATE = 3e-3
TEST_FRACTION = 0.2

LATENCY_FLOOR_S = 1e-3
"""Lower clip of a sampled compute time: a Gaussian tail must not give a zero or negative time."""

_NORMALIZATION_EPSILON = 1e-7  # keras.backend.epsilon(), the floor Normalization puts on the std

SigmaSource = Literal["published", "trace"]


@dataclass(frozen=True)
class ComputeModel:
    """A trained compute regressor evaluated in NumPy, with the σ_k noise model.

    Attributes:
        use_case: 1, 2 or 3.
        inputs: input column names, Γ first, ``n_processes`` last.
        input_mean: per-input standardisation mean.
        input_std: per-input standardisation std (already floored as Keras does).
        weights: dense layers' (kernel, bias), ReLU between them, linear last.
        output_scale: seconds per unit of the network's standardised output.
        output_offset: seconds added after scaling.
        sigma_by_k_s: σ_k in seconds for k = 1..5 (index k - 1).
    """

    use_case: int
    inputs: tuple[str, ...]
    input_mean: np.ndarray
    input_std: np.ndarray
    weights: tuple[tuple[np.ndarray, np.ndarray], ...]
    output_scale: float
    output_offset: float
    sigma_by_k_s: np.ndarray

    @property
    def gamma_columns(self) -> tuple[str, ...]:
        """Γ columns the caller passes to :meth:`predict_s` (may be empty: UC1)."""
        return self.inputs[:-1]

    @classmethod
    def load(
        cls,
        use_case: int,
        models_dir: Path | str = DEFAULT_MODELS_DIR,
        sigma_source: SigmaSource = "published",
    ) -> ComputeModel:
        """Load ``compute_uc{use_case}.npz`` / ``.json`` from ``models_dir``.

        Args:
            use_case: 1, 2 or 3.
            models_dir: folder written by ``traces/generate.py``.
            sigma_source: ``"published"`` = the paper's σ_k (facts.md); ``"trace"`` = the
                residual std per k of the regressor on its training trace (README §4.5).

        Raises:
            TraceError: missing or inconsistent model files.
            ValueError: unknown use case or sigma_source.
        """
        if use_case not in pub.USE_CASES:
            raise ValueError(f"use_case: {use_case!r} is not one of {pub.USE_CASES}")
        if sigma_source not in ("published", "trace"):
            raise ValueError(f"sigma_source: {sigma_source!r} is not 'published' or 'trace'")
        models_dir = Path(models_dir)
        npz_path = models_dir / f"compute_uc{use_case}.npz"
        json_path = models_dir / f"compute_uc{use_case}.json"
        for path in (npz_path, json_path):
            if not path.is_file():
                raise TraceError(f"{path}: compute model file not found (traces/generate.py makes the packaged "
                                 "ones; for your own traces: \"Measure your own\" in the documentation)")
        try:
            meta = json.loads(json_path.read_text())
            inputs = tuple(meta["inputs"])
            sigma = pub.SIGMA_S[use_case] if sigma_source == "published" else meta["trace_sigma_s"]
        except (ValueError, KeyError, TypeError) as exc:
            raise TraceError(f"{json_path}: not a compute model description ({type(exc).__name__}: {exc})") from None
        if inputs != MODEL_INPUTS[use_case]:
            raise TraceError(f"{json_path}: field 'inputs' is {list(inputs)}, expected {list(MODEL_INPUTS[use_case])}")
        try:
            with np.load(npz_path) as arrays:
                n_layers = int(arrays["n_layers"])
                weights = tuple((arrays[f"kernel_{i}"].astype(float), arrays[f"bias_{i}"].astype(float))
                                for i in range(n_layers))
                input_mean = arrays["input_mean"].astype(float)
                input_std = arrays["input_std"].astype(float)
                output_scale = float(arrays["output_scale"])
                output_offset = float(arrays["output_offset"])
        except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
            # A truncated or foreign file: numpy raises BadZipFile, EOFError or KeyError.
            raise TraceError(f"{npz_path}: truncated or not a compute model ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())}); rerun python traces/generate.py") from None
        return cls(use_case, MODEL_INPUTS[use_case], input_mean, input_std, weights, output_scale, output_offset, np.asarray(sigma, dtype=float))

    @classmethod
    def from_keras(cls, use_case: int, model: Any, sigma_by_k_s: Sequence[float]) -> ComputeModel:
        """Extract the arrays of a regressor built by :func:`build_regressor`."""
        normalization = model.get_layer("standardise")
        mean = np.asarray(normalization.mean, dtype=float).ravel()
        std = np.maximum(np.sqrt(np.asarray(normalization.variance, dtype=float).ravel()), _NORMALIZATION_EPSILON)
        dense = [layer for layer in model.layers if layer.name.startswith("dense_")]
        weights = tuple((np.asarray(layer.kernel, dtype=float), np.asarray(layer.bias, dtype=float)) for layer in dense)
        rescale = model.get_layer("to_seconds")
        return cls(
            use_case,
            MODEL_INPUTS[use_case],
            mean,
            std,
            weights,
            float(rescale.scale),
            float(rescale.offset),
            np.asarray(sigma_by_k_s, dtype=float),
        )

    def predict_s(self, gamma: np.ndarray | None, n_processes: np.ndarray | int) -> np.ndarray:
        """ŷ in seconds for each (request, k) pair, vectorised.

        Args:
            gamma: Γ values, shape (m, len(gamma_columns)) in ``gamma_columns`` order, or a
                single row of shape (len(gamma_columns),) broadcast against ``n_processes``;
                ``None`` or an empty array when Γ is empty (UC1).
            n_processes: k per pair, shape (m,) or scalar, values 1..5.

        Returns:
            Predictions, shape (m,) (or the broadcast length).
        """
        k = np.atleast_1d(np.asarray(n_processes, dtype=float))
        n_gamma = len(self.gamma_columns)
        if n_gamma == 0:
            features = k[:, None]
        else:
            g = np.asarray(gamma, dtype=float)
            g = g.reshape(1, n_gamma) if g.ndim == 1 else g
            if g.ndim != 2 or g.shape[1] != n_gamma:
                raise ValueError(f"gamma: shape {g.shape}, expected (m, {n_gamma}) for {self.gamma_columns}")
            rows = np.broadcast_shapes((g.shape[0],), k.shape)[0]
            features = np.column_stack([np.broadcast_to(g, (rows, n_gamma)), np.broadcast_to(k, (rows,))])
        hidden = (features - self.input_mean) / self.input_std
        for kernel, bias in self.weights[:-1]:
            hidden = np.maximum(hidden @ kernel + bias, 0.0)
        kernel, bias = self.weights[-1]
        return (hidden @ kernel + bias)[:, 0] * self.output_scale + self.output_offset

    def sigma_s(self, n_processes: np.ndarray | int) -> np.ndarray:
        """σ_k in seconds for each k (1..5)."""
        k = np.asarray(n_processes, dtype=np.int64)
        if np.any((k < 1) | (k > pub.MAX_PROCESSES)):
            raise ValueError(f"n_processes: values must be in 1..{pub.MAX_PROCESSES}")
        return self.sigma_by_k_s[k - 1]

    def sample_s(self, prediction_s: np.ndarray, n_processes: np.ndarray | int, standard_normal: np.ndarray) -> np.ndarray:
        """ŷ + σ_k z, clipped below at :data:`LATENCY_FLOOR_S`.

        The caller supplies the N(0, 1) draws ``z`` so it controls common random numbers.
        """
        z = np.asarray(standard_normal, dtype=float)
        return np.maximum(np.asarray(prediction_s, dtype=float) + self.sigma_s(n_processes) * z, LATENCY_FLOOR_S)


# ------------------------------------------------------------------------------ training


def build_regressor(
    use_case: int,
    input_mean: np.ndarray,
    input_variance: np.ndarray,
    output_mean_s: float,
    output_std_s: float,
    seed: int,
    hidden_units: Sequence[int] = HIDDEN_UNITS,
) -> Any:
    """A Keras MLP: standardise inputs -> ReLU hidden layers -> linear -> seconds.

    Standardisation and output scaling are layers, so the saved ``.keras`` file is complete.
    Initialisers are seeded per layer (no global random state).
    """
    import keras

    inputs = keras.Input(shape=(len(MODEL_INPUTS[use_case]),), name="features")
    x = keras.layers.Normalization(mean=input_mean, variance=input_variance, name="standardise")(inputs)
    for i, units in enumerate(hidden_units):
        x = keras.layers.Dense(
            units,
            activation="relu",
            kernel_initializer=keras.initializers.GlorotUniform(seed=seed + i),
            name=f"dense_{i}",
        )(x)
    x = keras.layers.Dense(
        1, kernel_initializer=keras.initializers.GlorotUniform(seed=seed + len(hidden_units)), name=f"dense_{len(hidden_units)}"
    )(x)
    outputs = keras.layers.Rescaling(scale=output_std_s, offset=output_mean_s, name="to_seconds")(x)
    return keras.Model(inputs, outputs, name=f"compute_uc{use_case}")


def split_rows(n_rows: int, seed: int, test_fraction: float = TEST_FRACTION) -> tuple[np.ndarray, np.ndarray]:
    """Seeded (train, test) row indices; the train indices are in shuffled order."""
    order = np.random.default_rng(seed).permutation(n_rows)
    n_test = int(round(test_fraction * n_rows))
    return order[n_test:], np.sort(order[:n_test])


def fit_metrics(y_true: np.ndarray, y_pred: np.ndarray) -> dict[str, float]:
    """R² and MAE (s)."""
    resid = y_true - y_pred
    return {
        "r2": float(1.0 - np.sum(resid**2) / np.sum((y_true - y_true.mean()) ** 2)),
        "mae_s": float(np.mean(np.abs(resid))),
    }


def train_regressor(trace: ComputeTrace, seed: int, epochs: int = EPOCHS) -> tuple[Any, dict[str, Any]]:
    """Train one use case's regressor on a compute trace.

    Input statistics come from the training rows only; batches follow a seeded pre-shuffled
    order (``shuffle=False``), so the run depends on ``seed`` alone.

    Returns:
        (Keras model, metadata with inputs, seed, fit on held-out rows and residual std per k).
    """
    import keras

    features = np.column_stack([trace.gamma_matrix(), trace.n_processes]).astype(float)
    latency = trace.latency_s
    train, test = split_rows(len(latency), seed)
    model = build_regressor(
        trace.use_case,
        features[train].mean(axis=0),
        features[train].var(axis=0),
        float(latency[train].mean()),
        float(latency[train].std()),
        seed,
    )
    # Cosine decay to zero: the last epochs average out minibatch noise instead of ending on a
    # noisy step (a constant rate left per-k biases of ~15 ms on UC1).
    steps = epochs * int(np.ceil(train.size / BATCH_SIZE))
    schedule = keras.optimizers.schedules.CosineDecay(LEARNING_RATE, decay_steps=steps)
    model.compile(optimizer=keras.optimizers.Adam(learning_rate=schedule), loss="mse")
    # The loss is in seconds²; Adam's steps do not depend on the loss scale, so one learning
    # rate serves every use case.
    model.fit(
        features[train],
        latency[train],
        epochs=epochs,
        batch_size=BATCH_SIZE,
        shuffle=False,
        verbose=0,
    )
    numpy_model = ComputeModel.from_keras(trace.use_case, model, pub.SIGMA_S[trace.use_case])
    prediction = numpy_model.predict_s(features[:, :-1], features[:, -1])
    resid = latency - prediction
    k = trace.n_processes
    meta = {
        "use_case": trace.use_case,
        "inputs": list(MODEL_INPUTS[trace.use_case]),
        "trace_file": trace.source.name,
        "seed": seed,
        "hidden_units": list(HIDDEN_UNITS),
        "epochs": epochs,
        "batch_size": BATCH_SIZE,
        "learning_rate": LEARNING_RATE,
        "fit": {"n_train": int(train.size), "n_test": int(test.size), **fit_metrics(latency[test], prediction[test])},
        "trace_sigma_s": [float(resid[k == kk].std()) for kk in range(1, pub.MAX_PROCESSES + 1)],
        "published_sigma_s": list(pub.SIGMA_S[trace.use_case]),
        "keras_version": keras.__version__,
    }
    return model, meta


def export_model(model: Any, meta: Mapping[str, Any], models_dir: Path) -> list[Path]:
    """Write ``.keras``, ``.npz`` (NumPy weights) and ``.json`` for one use case."""
    models_dir.mkdir(parents=True, exist_ok=True)
    use_case = int(meta["use_case"])
    stem = models_dir / f"compute_uc{use_case}"
    numpy_model = ComputeModel.from_keras(use_case, model, pub.SIGMA_S[use_case])
    arrays: dict[str, Any] = {
        "n_layers": np.array(len(numpy_model.weights)),
        "input_mean": numpy_model.input_mean,
        "input_std": numpy_model.input_std,
        "output_scale": np.array(numpy_model.output_scale),
        "output_offset": np.array(numpy_model.output_offset),
    }
    for i, (kernel, bias) in enumerate(numpy_model.weights):
        arrays[f"kernel_{i}"] = kernel
        arrays[f"bias_{i}"] = bias
    model.save(stem.with_suffix(".keras"))
    np.savez(stem.with_suffix(".npz"), **arrays)
    stem.with_suffix(".json").write_text(json.dumps(dict(meta), indent=2) + "\n")
    return [stem.with_suffix(s) for s in (".keras", ".npz", ".json")]


def train_compute_models(trace_dir: Path | str, models_dir: Path | str, seed: int, epochs: int = EPOCHS) -> list[Path]:
    """Train and export the regressors of all use cases from ``trace_dir``'s compute CSVs."""
    trace_dir, models_dir = Path(trace_dir), Path(models_dir)
    written: list[Path] = []
    for use_case in pub.USE_CASES:
        trace = load_compute(trace_dir / f"compute_uc{use_case}.csv", use_case)
        model, meta = train_regressor(trace, seed=seed + use_case, epochs=epochs)
        written += export_model(model, meta, models_dir)
    return written
