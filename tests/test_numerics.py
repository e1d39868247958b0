"""One numerical path on every x86-64: the pin TensorFlow loads under, what run.json and
summary.md say of it, and a decision forward pass that sums in one order on every processor."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from yafs_safetail import numerics
from yafs_safetail.methods.safetail.network import NumpyForward

_PRINT_PATH = ("import json, os, yafs_safetail.numerics as n; "
               "print(json.dumps([{k: os.environ.get(k) for k in n.PINNED_ENVIRONMENT}, "
               "n.numerical_path()]))")


def _fresh_interpreter(code: str, **env: str) -> list[dict[str, object]]:
    environment = {k: v for k, v in os.environ.items() if k not in numerics.PINNED_ENVIRONMENT}
    out = subprocess.run([sys.executable, "-c", code], env={**environment, **env},
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)


def test_importing_the_package_pins_the_path_before_tensorflow_loads():
    settings, path = _fresh_interpreter("import yafs_safetail; " + _PRINT_PATH)
    assert settings == numerics.PINNED_ENVIRONMENT
    assert path["settings"] == numerics.PINNED_ENVIRONMENT
    assert path["pinned"] is (os.uname().machine == numerics.PINNED_MACHINE)


def test_a_users_own_setting_is_kept_and_recorded_as_not_pinned():
    settings, path = _fresh_interpreter("import yafs_safetail; " + _PRINT_PATH, ONEDNN_MAX_CPU_ISA="AVX2")
    assert settings["ONEDNN_MAX_CPU_ISA"] == "AVX2"
    assert settings["TF_ENABLE_ONEDNN_OPTS"] == "0"
    assert path["pinned"] is False
    assert "ONEDNN_MAX_CPU_ISA=AVX2" in path["not_pinned_because"]


def test_tensorflow_loaded_before_the_package_is_recorded(monkeypatch):
    monkeypatch.setitem(numerics._state, "tensorflow_loaded_first", True)
    for name, value in numerics.PINNED_ENVIRONMENT.items():
        monkeypatch.setenv(name, value)
    path = numerics.numerical_path()
    assert path["pinned"] is False
    assert "TensorFlow was loaded before yafs_safetail" in path["not_pinned_because"]


def test_summary_md_says_when_the_network_did_not_take_the_pinned_path():
    import pandas as pd

    from yafs_safetail.results.report import summary_markdown
    from yafs_safetail.results.run_json import RunMetadata

    summary = pd.DataFrame({"method": ["Oracle"], "n_requests": [10], "p50_s": [1.0], "p90_s": [1.0],
                            "p95_s": [1.0], "p99_s": [1.0], "mean_access_rate": [1.0],
                            "mean_n_selected": [5.0], "mean_target_s": [1.0], "target_met_rate": [1.0],
                            "fallback_rate": [0.0], "thin_percentiles": [""]})

    def run(numerics_entry: dict[str, object]) -> RunMetadata:
        return RunMetadata(use_case=1, use_case_name="x", preset="paper", seed=0, n_servers=5,
                           beta=200, train_steps=10, test_steps=10, topology="t.json",
                           methods=["Oracle"], package_version="0", command="c",
                           extra={numerics.NUMERICS_KEY: numerics_entry})

    off = {"settings": {}, "pinned": False, "not_pinned_because": "the processor is aarch64, not x86-64"}
    noted = summary_markdown(summary, run(off))
    assert "**Not the published numerical path:** the processor is aarch64, not x86-64" in noted
    assert "Not the published numerical path" not in summary_markdown(summary, run({"pinned": True}))


def _in_order(inputs: np.ndarray, kernel: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """The layer as IEEE float32 arithmetic in one written-out order: product by product, input
    by input. Each step is one correctly rounded operation, so any processor gives these bits."""
    total = inputs[..., 0:1] * kernel[0]
    for i in range(1, kernel.shape[0]):
        total = total + inputs[..., i:i + 1] * kernel[i]
    return total + bias


def test_the_forward_pass_sums_in_one_order_whatever_blas_the_processor_picks():
    rng = np.random.default_rng(7)
    widths = [38, 128, 128, 64, 31]
    weights = []
    for fan_in, fan_out in zip(widths, widths[1:], strict=False):
        weights += [rng.normal(0, 0.2, (fan_in, fan_out)).astype(np.float32),
                    rng.normal(0, 0.1, fan_out).astype(np.float32)]
    states = rng.normal(size=(9, widths[0])).astype(np.float32)
    expected = states
    for k in range(0, len(weights), 2):
        expected = _in_order(expected, weights[k], weights[k + 1])
        if k + 2 < len(weights):
            expected = np.maximum(expected, np.float32(0.0))
    forward = NumpyForward(weights)
    batch = forward.logits(states)
    assert batch.dtype == np.float32
    np.testing.assert_array_equal(batch, expected)
    # A row of a batch is exactly the single state's output (a BLAS gemm and gemv need not agree).
    for row in range(len(states)):
        np.testing.assert_array_equal(forward.logits(states[row]), batch[row])
        assert forward.best_action(states[row]) == int(expected[row].argmax())


@pytest.mark.parametrize("bad", [[np.zeros((3, 2), np.float32)], []])
def test_the_forward_pass_still_refuses_malformed_weights(bad):
    with pytest.raises(ValueError, match="kernel/bias pairs"):
        NumpyForward(bad)


def _weights_digest(policy_file) -> str:
    import hashlib
    import zipfile

    with zipfile.ZipFile(policy_file) as archive:
        return hashlib.sha256(archive.read("model.weights.h5")).hexdigest()


@pytest.mark.slow
@pytest.mark.parametrize("cpu", ["EPYC-Milan", "Haswell"])
def test_an_emulated_avx2_processor_gives_the_same_files(tmp_path, cpu):
    """A stand-in for an AVX2-only machine, AMD or Intel: QEMU's user-mode emulator (Debian's
    qemu-user) shows the program that processor's instruction set. On the pinned path the run's
    files and trained weights are those of this machine's; unpinned they differ
    (docs/results.md, "Same files on every processor")."""
    import shutil

    qemu = shutil.which("qemu-x86_64")
    if qemu is None or os.uname().machine != numerics.PINNED_MACHINE:
        pytest.skip("needs qemu-x86_64 (apt-get install qemu-user) on an x86-64 machine")
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "experiments" / "run_usecase.py"
    args = [str(script), "--uc", "1", "--steps-scale", "0.05", "--no-figures", "-q"]
    environment = {k: v for k, v in os.environ.items() if k not in numerics.PINNED_ENVIRONMENT}
    for name, command in (("here", [sys.executable]), ("emulated", [qemu, "-cpu", cpu, sys.executable])):
        subprocess.run([*command, *args, "--out", str(tmp_path / name)], env=environment,
                       capture_output=True, text=True, check=True, timeout=3000)
    here, emulated = tmp_path / "here", tmp_path / "emulated"
    assert (here / "requests.csv").read_bytes() == (emulated / "requests.csv").read_bytes()
    assert _weights_digest(here / "policy.keras") == _weights_digest(emulated / "policy.keras")
