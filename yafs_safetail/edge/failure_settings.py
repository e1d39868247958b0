"""How often each edge server fails and how long a user waits: :class:`FailureSettings`.

Standard library only: a failure sweep's options and ``contention.config.ContentionConfig``
(whose default is "no failures") need these settings before NumPy loads. ``edge.failures``
draws the outages from them and re-exports both names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

#: Mean time to repair when only a mean time to failure is given: a minute, the load trace's
#: resolution (one row per minute), so an outage outlasts a request but not a load change.
DEFAULT_MTTR_S = 60.0


@dataclass(frozen=True)
class FailureSettings:
    """Which servers fail, and how long the user waits for a reply.

    Attributes:
        mttf_s: mean time to failure of each server (exponential); None: no random failures.
        mttr_s: mean time to repair (exponential).
        down_file: a CSV of scripted down intervals (``server,down_s,up_s``), or None.
        timeout_s: how long the user waits for the first reply before it takes the on-device
            fallback; None: :func:`~yafs_safetail.edge.failures.effective_timeout_s` decides.
    """

    mttf_s: float | None = None
    mttr_s: float = DEFAULT_MTTR_S
    down_file: Path | None = None
    timeout_s: float | None = None

    def __post_init__(self) -> None:
        if self.mttf_s is not None and not (math.isfinite(self.mttf_s) and self.mttf_s > 0):
            raise ValueError(f"mttf_s: must be a positive number of seconds, got {self.mttf_s!r}")
        if not (math.isfinite(self.mttr_s) and self.mttr_s > 0):
            raise ValueError(f"mttr_s: must be a positive number of seconds, got {self.mttr_s!r}")
        if self.timeout_s is not None and not (math.isfinite(self.timeout_s) and self.timeout_s > 0):
            raise ValueError(f"timeout_s: must be a positive number of seconds, got {self.timeout_s!r}")

    @property
    def enabled(self) -> bool:
        """Whether any server can fail."""
        return self.mttf_s is not None or self.down_file is not None

    @property
    def unavailability(self) -> float:
        """The stationary probability that a server is down from random failures alone."""
        if self.mttf_s is None:
            return 0.0
        return self.mttr_s / (self.mttf_s + self.mttr_s)

    @classmethod
    def for_unavailability(cls, probability: float, mttr_s: float = DEFAULT_MTTR_S,
                           timeout_s: float | None = None) -> FailureSettings:
        """Random failures with this stationary down probability (0: none) and repair time."""
        if not 0.0 <= probability < 1.0:
            raise ValueError(f"failure probability: must be in [0, 1), got {probability!r}")
        if probability == 0.0:
            return cls(mttr_s=mttr_s, timeout_s=timeout_s)
        return cls(mttf_s=mttr_s * (1.0 - probability) / probability, mttr_s=mttr_s, timeout_s=timeout_s)
