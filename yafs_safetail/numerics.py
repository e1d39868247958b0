"""One numerical path for SafeTail's network on every x86-64 processor.

TensorFlow's CPU kernels choose their code by the processor at run time: its oneDNN operations
(on by default where the processor has AVX-512 VNNI or newer) and the oneDNN matrix-multiply
kernel inside its Eigen contractions (always) run AVX-512, AVX2 or SSE code, each summing in
its own order. SafeTail's decisions are argmaxes over near-tied outputs, so the last bits
decide the learned policy: the same seed trained three policies on three processors.

Measured (docs/results.md, "Same files on every processor"): with oneDNN's operations off and
its kernels capped at SSE4.1, an AVX-512 and an AVX2-only x86-64 give byte-identical results
files, SafeTail's included; capping at AVX2 does not (the two AVX2 paths still differ).
:func:`pin_numerical_path` sets both before TensorFlow loads. The decisions' NumPy forward pass
does not go through a BLAS library (``methods.safetail.network.NumpyForward``), so NumPy's
kernels choose nothing there.

Standard library only: the package imports it first, before anything can load TensorFlow.
"""

from __future__ import annotations

import os
import platform
import sys

#: What the published files were made with, set unless the user set the variable first.
PINNED_ENVIRONMENT: dict[str, str] = {
    # oneDNN's own operations off: TensorFlow runs its Eigen kernels, as on a processor
    # without AVX-512 VNNI, where oneDNN's operations are off by default.
    "TF_ENABLE_ONEDNN_OPTS": "0",
    # oneDNN's matrix-multiply kernel (used inside the Eigen contractions too) capped at SSE4.1.
    "ONEDNN_MAX_CPU_ISA": "SSE41",
}
#: The architecture the pin is proven on; elsewhere oneDNN's cap means nothing.
PINNED_MACHINE = "x86_64"
#: ``run.json`` key: the numerical path a run's network took (:func:`numerical_path`).
NUMERICS_KEY = "numerics"

_state = {"tensorflow_loaded_first": False}


def pin_numerical_path() -> None:
    """Set :data:`PINNED_ENVIRONMENT`'s variables that the user has not set.

    Called when the package is imported. It cannot reach a TensorFlow already loaded: that
    is recorded, and :func:`numerical_path` then reports the path as not pinned. The variables
    stay in ``os.environ``, so worker processes inherit them.
    """
    if "tensorflow" in sys.modules:
        _state["tensorflow_loaded_first"] = True
    for name, value in PINNED_ENVIRONMENT.items():
        os.environ.setdefault(name, value)


def numerical_path() -> dict[str, object]:
    """What ``run.json`` records: the variables in force, and whether they are the pinned path
    on the architecture it was proven on (``pinned``), with the reason when not."""
    settings = {name: os.environ.get(name) for name in PINNED_ENVIRONMENT}
    reasons = []
    if platform.machine() not in (PINNED_MACHINE, "AMD64"):
        reasons.append(f"the processor is {platform.machine() or 'unknown'}, not x86-64")
    changed = sorted(name for name, value in settings.items() if value != PINNED_ENVIRONMENT[name])
    if changed:
        reasons.append("set otherwise: " + ", ".join(f"{name}={settings[name]}" for name in changed))
    if _state["tensorflow_loaded_first"]:
        reasons.append("TensorFlow was loaded before yafs_safetail")
    return {"settings": settings, "pinned": not reasons,
            **({"not_pinned_because": "; ".join(reasons)} if reasons else {})}


def not_pinned_note(numerics: dict[str, object]) -> str:
    """One markdown paragraph for a report whose network did not take the pinned path."""
    return ("**Not the published numerical path:** " + str(numerics.get("not_pinned_because", ""))
            + ". The published numbers and the golden files were made on x86-64 with "
            + ", ".join(f"`{name}={value}`" for name, value in PINNED_ENVIRONMENT.items())
            + "; SafeTail's rows may differ in the last bits, and so may its learned policy "
            "(docs/results.md, \"Same files on every processor\").")
