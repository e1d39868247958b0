"""The SafeTail learner: ε-greedy decisions (Eq. 3) and training rounds on target vectors."""

from __future__ import annotations

import json
import math
import os
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from yafs_safetail.policy.actions import n_actions as count_actions
from yafs_safetail.policy.network import (
    NumpyForward,
    build_network,
    enable_determinism,
    make_round_updates,
)
from yafs_safetail.policy.presets import LearnerConfig
from yafs_safetail.policy.reward import target_vector

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
    staging = path.with_name(f".{path.name}.tmp")
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
    os.replace(staging, path)


def read_policy_sidecar(path: str | Path) -> dict[str, Any]:
    """The JSON sidecar of a saved policy (n_servers, state_dim, config, ...), read without
    TensorFlow, so a mismatch can be reported before anything heavy is loaded.

    Raises:
        PolicyFileError: a missing or malformed sidecar.
    """
    sidecar_path = Path(str(path) + SIDECAR_SUFFIX)
    if not sidecar_path.is_file():
        raise PolicyFileError(f"{sidecar_path}: file not found (saved with the policy)")
    try:
        info = json.loads(sidecar_path.read_text())
        int(info["n_servers"]), int(info["state_dim"]), LearnerConfig.from_dict(info["config"])
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise PolicyFileError(f"{sidecar_path}: malformed sidecar: {exc}") from exc
    return info


class SafeTailLearner:
    """The FNN policy, its ε-greedy exploration, and its training rounds.

    Typical use from a selection::

        state = encode_state(obs, scales)
        action = learner.act(state, explore=True)      # then dispatch to subset_of(action, n)
        ...                                            # when the request completes:
        r = reward(latency_s, target_s, len(subset), n, learner.config.delta)
        learner.observe(state, action, r)              # trains every κ tuples

    Randomness: one ``SeedSequence(seed)`` gives the exploration generator, the minibatch
    shuffling generator and the initial-weight seeds; nothing is drawn from global state.

    Attributes:
        n_servers: n.
        n_actions: 2^n - 1.
        state_dim: Length of the encoded state.
        config: The preset.
        metadata: Free-form JSON-serialisable data saved with the policy (e.g. the state
            scales); empty unless given.
    """

    def __init__(
        self,
        n_servers: int,
        state_dim: int,
        config: LearnerConfig,
        seed: int,
        *,
        training: bool = True,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        """Build a fresh network.

        Args:
            n_servers: n, 1..10.
            state_dim: Length of the encoded state (``state_dim(n, g, d)``).
            config: A preset (see :func:`yafs_safetail.policy.presets.get_preset`).
            seed: The run's seed; also seeds Keras/TensorFlow process-wide (see
                :func:`yafs_safetail.policy.network.enable_determinism`).
            training: False for an evaluation-only learner.
            metadata: Saved alongside the weights.

        Raises:
            ValueError: bad ``n_servers``, ``state_dim`` or ``seed``.
        """
        self.n_actions = count_actions(n_servers)
        if isinstance(state_dim, bool) or not isinstance(state_dim, int) or state_dim < 1:
            raise ValueError(f"state_dim must be an integer >= 1, got {state_dim!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        self.n_servers = int(n_servers)
        self.state_dim = state_dim
        self.config = config
        self.metadata: dict[str, Any] = dict(metadata or {})
        self._training = bool(training)
        self._seed = seed
        explore_seq, shuffle_seq, init_seq = np.random.SeedSequence(seed).spawn(3)
        self._explore_rng = np.random.default_rng(explore_seq)
        self._shuffle_rng = np.random.default_rng(shuffle_seq)
        enable_determinism(seed)
        self._model = build_network(
            state_dim, self.n_actions, config, int(init_seq.generate_state(1)[0])
        )
        self._forward = NumpyForward.from_model(self._model)
        capacity = config.replay_capacity
        self._states = np.zeros((capacity, state_dim), dtype=np.float32)
        self._targets = np.zeros((capacity, self.n_actions), dtype=np.float32)
        self._n_stored = 0
        self._n_buffered = 0
        self._n_rounds = 0
        self._round_updates: Any = None
        self.last_round_loss: float | None = None

    # -- state -------------------------------------------------------------------------------

    @property
    def training(self) -> bool:
        """False in evaluation-only mode: ``act`` always exploits, ``observe`` stores nothing."""
        return self._training

    @training.setter
    def training(self, value: bool) -> None:
        self._training = bool(value)

    @property
    def epsilon(self) -> float:
        """Current ε: ε_start - decays·ε_decay, floored at ε_min, where decays counts training
        rounds, or stored tuples with ``config.epsilon_per_step``."""
        c = self.config
        decays = self._n_stored if c.epsilon_per_step else self._n_rounds
        return max(c.epsilon_min, c.epsilon_start - decays * c.epsilon_decay)

    @property
    def n_training_rounds(self) -> int:
        """Training rounds run so far."""
        return self._n_rounds

    @property
    def n_stored(self) -> int:
        """(state, action, reward) tuples observed in training mode so far."""
        return self._n_stored

    @property
    def model(self) -> Any:
        """The Keras model (read it; train only through :meth:`observe`)."""
        return self._model

    # -- decisions and learning --------------------------------------------------------------

    def act(self, state: np.ndarray, explore: bool) -> int:
        """Choose an action for one encoded state (Eq. 3).

        With ``explore`` in training mode: a uniformly random action with probability ε,
        otherwise the argmax of the network. Without ``explore``, or in evaluation mode:
        always the argmax (ε is not used and no random number is drawn).

        Args:
            state: float32 vector of length ``state_dim`` (from ``encode_state``).
            explore: Whether ε-greedy exploration applies (training phase).

        Returns:
            The action index, 0..2^n - 2.
        """
        if explore and self._training and self._explore_rng.random() < self.epsilon:
            return int(self._explore_rng.integers(self.n_actions))
        return self._forward.best_action(state)

    def observe(self, state: np.ndarray, action: int, reward: float) -> bool:
        """Store one (ω, A, R) tuple; run a training round every κ stored tuples.

        In evaluation mode nothing is stored and nothing trains.

        Args:
            state: The encoded state the action was chosen for.
            action: The action taken.
            reward: Its Eq. 5 reward (<= 0).

        Returns:
            True if this call ran a training round.

        Raises:
            ValueError: wrong state shape, action out of range or a positive reward.
        """
        if not self._training:
            return False
        if state.shape != (self.state_dim,):
            raise ValueError(f"state must have shape ({self.state_dim},), got {state.shape}")
        slot = self._n_buffered % self.config.replay_capacity
        self._targets[slot] = target_vector(action, reward, self.n_servers)
        self._states[slot] = state
        self._n_buffered += 1
        self._n_stored += 1
        if self._n_stored % self.config.kappa:
            return False
        self._train_round()
        return True

    def _train_round(self) -> None:
        c = self.config
        n_rows = min(c.replay_capacity, self._n_buffered)
        # The ring buffer holds exactly the most recent n_rows tuples in slots 0..n_rows-1.
        states = self._states[:n_rows]
        targets = self._targets[:n_rows]
        if c.replay_sampling == "uniform":
            batches = np.stack([
                self._shuffle_rng.choice(n_rows, size=c.batch_size, replace=False)
                for _ in range(c.updates_per_round)
            ])
            if self._round_updates is None:
                self._round_updates = make_round_updates(self._model)
            self.last_round_loss = self._round_updates(states, targets, batches)
        else:
            losses = []
            for _ in range(c.epochs_per_round):
                order = self._shuffle_rng.permutation(n_rows)
                for start in range(0, n_rows, c.batch_size):
                    batch = order[start:start + c.batch_size]
                    losses.append(float(self._model.train_on_batch(states[batch], targets[batch])))
            self.last_round_loss = float(np.mean(losses))
        self._forward = NumpyForward.from_model(self._model)
        self._n_rounds += 1

    def predict_probabilities(self, states: np.ndarray) -> np.ndarray:
        """Softmax outputs of the Keras model for a batch of states (for analysis, not speed)."""
        return np.asarray(self._model(np.asarray(states, dtype=np.float32), training=False))

    # -- persistence -------------------------------------------------------------------------

    def save(self, path: str | Path) -> Path:
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
        self._model.save(path)
        _make_reproducible(path)
        sidecar = {
            "version": _SIDECAR_VERSION,
            "n_servers": self.n_servers,
            "state_dim": self.state_dim,
            "seed": self._seed,
            "config": self.config.to_dict(),
            "n_training_rounds": self._n_rounds,
            "n_stored": self._n_stored,
            "epsilon": self.epsilon,
            "explore_rng": self._explore_rng.bit_generator.state,
            "shuffle_rng": self._shuffle_rng.bit_generator.state,
            "metadata": self.metadata,
        }
        Path(str(path) + SIDECAR_SUFFIX).write_text(json.dumps(sidecar, indent=2, sort_keys=True))
        return path

    @classmethod
    def load(cls, path: str | Path, *, training: bool = False) -> SafeTailLearner:
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
            learner = cls(
                int(info["n_servers"]), int(info["state_dim"]), config, int(info["seed"]),
                training=training, metadata=info.get("metadata") or {},
            )
            n_rounds = int(info["n_training_rounds"])
            n_stored = int(info["n_stored"])
            saved_epsilon = float(info["epsilon"])
            explore_state, shuffle_state = info["explore_rng"], info["shuffle_rng"]
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise PolicyFileError(f"{sidecar_path}: malformed sidecar: {exc}") from exc
        try:
            model = keras.models.load_model(path, safe_mode=True)
        except (ValueError, OSError) as exc:
            raise PolicyFileError(f"{path}: cannot load the network: {exc}") from exc
        expected_in = (None, learner.state_dim)
        expected_out = (None, learner.n_actions)
        if tuple(model.input_shape) != expected_in or tuple(model.output_shape) != expected_out:
            raise PolicyFileError(
                f"{path}: network maps {model.input_shape} -> {model.output_shape}, sidecar "
                f"says {expected_in} -> {expected_out}"
            )
        learner._model = model
        learner._round_updates = None
        learner._forward = NumpyForward.from_model(model)
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
