"""A run's learning methods: SafeTail (from the preset, or a saved policy) and users' learners.

Everything after this module treats them alike (``runs.training``, ``runs.evaluation``,
``runs.provenance``): each is a :class:`~yafs_safetail.methods.learning.LearningPolicy`.
Building SafeTail imports TensorFlow, so a run calls :func:`make_learners` only after its
worker processes have forked.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from yafs_safetail.methods.learning import LearningPolicy
from yafs_safetail.methods.policy import PolicyError
from yafs_safetail.methods.registry import SAFETAIL, UserMethod, method_rng
from yafs_safetail.methods.safetail.assemble import make_safetail

if TYPE_CHECKING:
    from yafs_safetail.methods.safetail.policy import SafeTailPolicy
    from yafs_safetail.runs.experiment import ExperimentConfig, _Inputs


def users_learners(methods: Sequence[UserMethod]) -> tuple[UserMethod, ...]:
    """The users' methods that learn (they train in this process; the others go to workers)."""
    return tuple(method for method in methods if method.learns)


def learner_names(config: ExperimentConfig) -> list[str]:
    """The names of the run's learning methods, in training order (:func:`make_learners`)."""
    return [SAFETAIL, *(method.name for method in users_learners(config.methods))]


def check_learners(config: ExperimentConfig, trains: bool) -> None:
    """Refuse (PolicyError) a user's learner in a run without a training phase (``--policy``)."""
    learners = users_learners(config.methods)
    if learners and not trains:
        raise PolicyError(f"--method {learners[0].spec}: a learning method needs a training "
                          "phase, and a run with --policy has none; give one or the other")


def make_learners(config: ExperimentConfig, inputs: _Inputs,
                  timings_s: dict[str, float]) -> list[LearningPolicy]:
    """The run's learning methods in training order: SafeTail, then the users' learners.

    Records in ``timings_s["tf_import"]`` the seconds TensorFlow took to import.
    """
    started = time.perf_counter()
    # SafeTail builds its network with Keras; importing it (and TensorFlow) takes seconds the
    # first time, so it is timed on its own.
    importlib.import_module("keras")
    timings_s["tf_import"] = time.perf_counter() - started
    n_servers = inputs.scenario.n_servers
    return [_safetail(config, inputs),
            *(method.make_learner(n_servers, method_rng(config.seed, method.name))
              for method in users_learners(config.methods))]


def _safetail(config: ExperimentConfig, inputs: _Inputs) -> SafeTailPolicy:
    """SafeTail with a fresh learner of the run's preset (and ``--objective``, with the reward it
    brings: the value learner's own, D13, else Eq. 5; copies sent all at once, as the paper's),
    or the saved one of ``--policy``."""
    policy = make_safetail(inputs.use_case, inputs.scenario, inputs.learner_config, config.seed,
                           metadata={"topology": str(config.topology)})
    if config.policy is not None:
        policy.load(config.policy)
    return policy
