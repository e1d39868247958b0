"""Saving and loading a SafeTail learner: the Keras network plus a JSON sidecar, byte-identical
for the same weights, and the sidecar readable without TensorFlow."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Any

from yafs_safetail.methods.safetail.learner import SafeTailLearner
from yafs_safetail.methods.safetail.network import fast_forward
from yafs_safetail.methods.safetail.presets import LearnerConfig

#: A run's saved SafeTail in its results folder (``SafeTailPolicy.policy_file``); the sidecar
#: is beside it, with :data:`SIDECAR_SUFFIX` added.
POLICY_FILE = "policy.keras"
SIDECAR_SUFFIX = ".json"
_SIDECAR_VERSION = 1


class PolicyFileError(ValueError):
    """A saved policy (``.keras`` file or its JSON sidecar) is missing or inconsistent."""


#: What a saved policy records as its save date: a fixed value, so that the same weights give
#: a byte-identical ``.keras`` file (Keras writes the wall-clock time otherwise).
FIXED_SAVE_DATE = "1980-01-01@00:00:00"
_FIXED_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


_SHARED_OBJECT_ID = re.compile(r'"shared_object_id": (\d+)')


def _renumber_shared_objects(config_text: str) -> str:
    """Replace Keras's ``shared_object_id`` values (Python object addresses, different in every
    process) by 1, 2, ... in order of first appearance; equal ids stay equal, which is all
    Keras uses them for when loading."""
    numbers: dict[str, int] = {}

    def renumber(match: re.Match[str]) -> str:
        number = numbers.setdefault(match.group(1), len(numbers) + 1)
        return f'"shared_object_id": {number}'

    return _SHARED_OBJECT_ID.sub(renumber, config_text)


def _make_reproducible(path: Path) -> None:
    """Rewrite a ``.keras`` archive with a fixed save date and fixed entry timestamps.

    The weights are already deterministic; Keras's ``metadata.json`` date, the object
    addresses in ``config.json`` and the zip entries' modification times are not.
    """
    handle, staging_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(handle)
    staging = Path(staging_name)
    try:
        _rewrite(path, staging)
    except BaseException:
        staging.unlink(missing_ok=True)  # the temporary file made just above
        raise
    # mkstemp made the rewrite private (0600); the policy keeps the mode Keras's ordinary
    # write gave it (the umask's), so that a shared results folder's policy is readable.
    shutil.copymode(path, staging)
    os.replace(staging, path)


def _rewrite(path: Path, staging: Path) -> None:
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(staging, "w", zipfile.ZIP_DEFLATED) as target:
        for entry in source.infolist():
            data = source.read(entry.filename)
            if entry.filename == "metadata.json":
                metadata = json.loads(data)
                metadata["date_saved"] = FIXED_SAVE_DATE
                data = json.dumps(metadata).encode("utf-8")
            elif entry.filename == "config.json":
                data = _renumber_shared_objects(data.decode("utf-8")).encode("utf-8")
            info = zipfile.ZipInfo(entry.filename, date_time=_FIXED_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = entry.external_attr
            target.writestr(info, data)


def read_policy_sidecar(path: str | Path) -> dict[str, Any]:
    """The JSON sidecar of a saved policy (n_servers, state_dim, config, ...), read without
    TensorFlow, so a mismatch can be reported before anything heavy is loaded.

    Raises:
        PolicyFileError: a missing or malformed sidecar.
    """
    if Path(path).is_file() and not zipfile.is_zipfile(path):
        raise PolicyFileError(f"{path}: not a complete .keras file (truncated, or not a saved policy)")
    sidecar_path = Path(str(path) + SIDECAR_SUFFIX)
    if not sidecar_path.is_file():
        raise PolicyFileError(f"{sidecar_path}: file not found (saved with the policy)")
    try:
        info = json.loads(sidecar_path.read_text())
        int(info["n_servers"]), int(info["state_dim"]), LearnerConfig.from_dict(info["config"])
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise PolicyFileError(f"{sidecar_path}: malformed sidecar: {exc}") from exc
    return info


def save_learner(learner: SafeTailLearner, path: str | Path) -> Path:
    """Write the network to ``path`` (must end in ``.keras``) and a JSON sidecar next to it.

    The sidecar (``<path>.json``) holds n, state_dim, the config, ε's round count, the
    tuple count, the generators' states and ``metadata``. The tuple buffer is not saved:
    continuing training after ``load`` starts with an empty buffer and drops tuples stored
    since the last round (for ``paper``, whose rounds use only the κ tuples since the
    previous round, a policy saved right after a round resumes exactly).

    Returns:
        The path of the ``.keras`` file.
    """
    path = Path(path)
    if path.suffix != ".keras":
        raise ValueError(f"{path}: a saved policy must end in .keras")
    learner._model.save(path)
    _make_reproducible(path)
    sidecar = {
        "version": _SIDECAR_VERSION,
        "n_servers": learner.n_servers,
        "state_dim": learner.state_dim,
        "seed": learner._seed,
        "config": learner.config.to_dict(),
        "n_training_rounds": learner._n_rounds,
        "n_stored": learner._n_stored,
        "epsilon": learner.epsilon,
        "explore_rng": learner._explore_rng.bit_generator.state,
        "shuffle_rng": learner._shuffle_rng.bit_generator.state,
        "metadata": learner.metadata,
    }
    Path(str(path) + SIDECAR_SUFFIX).write_text(json.dumps(sidecar, indent=2, sort_keys=True))
    return path

def load_learner(path: str | Path, *, training: bool = False) -> SafeTailLearner:
    """Load a policy written by :meth:`save` (Keras ``safe_mode=True``).

    Args:
        path: The ``.keras`` file; its sidecar must sit next to it.
        training: False (default) for evaluation only; True continues training from the
            saved ε, round count and generator states.

    Raises:
        PolicyFileError: a missing file, or a sidecar inconsistent with the network.
    """
    import keras

    path = Path(path)
    sidecar_path = Path(str(path) + SIDECAR_SUFFIX)
    for p in (path, sidecar_path):
        if not p.is_file():
            raise PolicyFileError(f"{p}: file not found")
    try:
        info = json.loads(sidecar_path.read_text())
        if info.get("version") != _SIDECAR_VERSION:
            raise ValueError(f"version must be {_SIDECAR_VERSION}, got {info.get('version')!r}")
        config = LearnerConfig.from_dict(info["config"])
        learner = SafeTailLearner(
            int(info["n_servers"]), int(info["state_dim"]), config, int(info["seed"]),
            training=training, metadata=info.get("metadata") or {},
        )
        n_rounds = int(info["n_training_rounds"])
        n_stored = int(info["n_stored"])
        saved_epsilon = float(info["epsilon"])
        explore_state, shuffle_state = info["explore_rng"], info["shuffle_rng"]
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise PolicyFileError(f"{sidecar_path}: malformed sidecar: {exc}") from exc
    # Registers a custom loss (the value objective's) the network was compiled with.
    config.learning_objective.compile_loss()
    try:
        model = keras.models.load_model(path, safe_mode=True)
    except (ValueError, OSError) as exc:
        raise PolicyFileError(f"{path}: cannot load the network: {exc}") from exc
    expected_in = (None, learner.state_dim)
    expected_out = (None, config.n_networks * learner.n_actions)
    if tuple(model.input_shape) != expected_in or tuple(model.output_shape) != expected_out:
        raise PolicyFileError(
            f"{path}: network maps {model.input_shape} -> {model.output_shape}, sidecar "
            f"says {expected_in} -> {expected_out}"
        )
    learner._model = model
    learner._round_updates = None
    learner._forward = fast_forward(model, config)
    learner._n_rounds = n_rounds
    learner._n_stored = n_stored
    if not math.isclose(learner.epsilon, saved_epsilon, abs_tol=1e-12):
        raise PolicyFileError(f"{sidecar_path}: epsilon does not match the saved counts")
    # The buffer is not saved: drop the partial batch so rounds stay every κ tuples (with
    # ε decaying per step, ε then resumes from the last round's value).
    learner._n_stored = n_stored // config.kappa * config.kappa
    learner._explore_rng.bit_generator.state = explore_state
    learner._shuffle_rng.bit_generator.state = shuffle_state
    return learner
