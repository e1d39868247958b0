"""Methods that learn: :class:`LearningPolicy`, the protocol a run trains any learner through.

A run (``runs.experiment``) gives every learning method the same life, SafeTail and a user's
``--method file.py:Class`` alike:

1. ``begin_phase("train")``, then the training phase's requests (``choose`` and ``feedback``
   as for any policy), on the same requests as every other learner; between two requests the
   run may take :meth:`~LearningPolicy.checkpoint_state` (``--resume`` gives it back to
   :meth:`~LearningPolicy.restore_checkpoint_state` in a fresh process and continues there);
2. :meth:`~LearningPolicy.end_training`, whose line goes to the run's log;
3. ``begin_phase("test")``, then the test phase's requests (the same ones every method gets);
4. :meth:`~LearningPolicy.save` into the results folder, as :meth:`~LearningPolicy.policy_file`,
   and :meth:`~LearningPolicy.run_json_fields` into ``run.json``.

A learner in a few lines (``tests/counting_learner.py`` is a whole one)::

    class Counting(LearningPolicy):
        def choose(self, observation):
            return [int(np.argmin(self.misses))]
        def feedback(self, record):
            if self.training:
                self.misses[record.servers[0]] += record.latency_s > record.target_s
        ...  # save, load, checkpoint_state, restore_checkpoint_state
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from yafs_safetail.methods.policy import Policy

#: The phases a run drives a learning method through, in order.
TRAIN_PHASE = "train"
TEST_PHASE = "test"


class LearningPolicy(Policy):
    """A :class:`~yafs_safetail.methods.policy.Policy` with a training phase before its test.

    Everything it learns must come from the requests it is given, and every random draw from
    its own ``rng`` (or generators derived from it), so that the same seed gives the same
    results and a resumed training continues exactly.

    Attributes:
        training: True during the training phase (explore and learn), False while testing
            (act on what was learned, learn nothing); set by :meth:`begin_phase`.
        decision_time_s: wall time spent choosing (optional: the run reports it).
        training_time_s: wall time spent learning (optional: the run reports it).
    """

    training: bool = False
    decision_time_s: float = 0.0
    training_time_s: float = 0.0

    def begin_phase(self, phase: str) -> None:
        """Called before each phase, :data:`TRAIN_PHASE` then :data:`TEST_PHASE`.

        The default sets :attr:`training`; override to do more (and call this one).
        """
        self.training = phase == TRAIN_PHASE

    def end_training(self) -> str:
        """Called once when the training phase ends; returns a line for the run's log (e.g.
        what was learned), or ``""`` for none."""
        return ""

    def policy_file(self) -> str:
        """The file name :meth:`save` writes in the results folder (default ``NAME.policy``)."""
        return f"{self.name}.policy"

    def save(self, path: Path) -> None:
        """Write what was learned to ``path`` (the same learning gives the same bytes)."""
        raise NotImplementedError(f"{type(self).__name__} must implement save(path)")

    def load(self, path: Path) -> None:
        """Replace what this policy learned by what :meth:`save` wrote to ``path``."""
        raise NotImplementedError(f"{type(self).__name__} must implement load(path)")

    def checkpoint_state(self) -> object:
        """Everything training has changed so far (learned values, counters, the state of
        every generator it draws from), as one picklable object; taken between two requests."""
        raise NotImplementedError(f"{type(self).__name__} must implement checkpoint_state()")

    def restore_checkpoint_state(self, state: object) -> None:
        """Continue from :meth:`checkpoint_state`'s object, in a freshly built policy: the rest
        of the training must then be what it would have been without the interruption."""
        raise NotImplementedError(f"{type(self).__name__} must implement restore_checkpoint_state(state)")

    def run_json_fields(self) -> dict[str, Any]:
        """Keys this method adds to ``run.json`` (JSON values; none by default). Two learning
        methods of one run may not give the same key."""
        return {}
