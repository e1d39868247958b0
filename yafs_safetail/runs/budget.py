"""How big a run may be: refuse budgets too small to mean anything or too large for the machine.

The per-request sizes were measured on the default UC1 run (54,000 request rows: requests.csv
9.5 MB, YAFS CSVs 69 MB); the memory per step is the pre-drawn world (1.1 kB per step) plus the
records held until they are written. The times per request were measured on the same run in one
process (``--workers 1``) on a 2-core machine: 10,000 training requests took 5.4 s of learner
time, 54,000 simulated requests 5.5 s and their writing 1.7 s; a warning gives the estimate when
it exceeds ``WARN_SECONDS``.
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING

from yafs_safetail.methods.safetail.presets import LearnerConfig

if TYPE_CHECKING:
    from yafs_safetail.settings.experiment import ExperimentConfig

log = logging.getLogger(__name__)


class BudgetError(ValueError):
    """A step budget the run refuses (one line saying why and what to do)."""


# ``--force`` lifts the upper limits.
REQUESTS_CSV_BYTES_PER_ROW = 180
YAFS_CSV_BYTES_PER_ROW = 1_300
MEMORY_BYTES_PER_STEP = 3_000
MAX_DISK_BYTES = 10e9
WARN_DISK_BYTES = 1e9
MAX_MEMORY_BYTES = 4e9
SECONDS_PER_TRAINING_STEP = 5.4e-4
SECONDS_PER_ROW = 1.3e-4
WARN_SECONDS = 600.0
#: Fewer test requests than this give percentiles that mean nothing.
MIN_TEST_STEPS = 10


def check_budget(config: ExperimentConfig, full: LearnerConfig, learner: LearnerConfig,
                 test_steps: int, n_methods: int) -> None:
    """Refuse a budget too small to mean anything or (without ``force``) too large for the
    machine; log a warning above 1 GB of results (shown even with ``--quiet``). ``full`` is the preset at full budget."""
    train_steps = 0 if config.policy is not None else learner.train_steps
    scale = f"--steps-scale {config.steps_scale:g}"
    if config.policy is None and train_steps < learner.kappa:
        smallest = math.ceil(learner.kappa / full.train_steps * 1e4) / 1e4
        raise BudgetError(
            f"{scale}: {train_steps} training requests, fewer than κ = {learner.kappa}: SafeTail "
            f"would never train; use --steps-scale {smallest:g} or more"
        )
    if test_steps < MIN_TEST_STEPS:
        raise BudgetError(f"{scale}: {test_steps} test requests, fewer than {MIN_TEST_STEPS}: "
                          "its percentiles would mean nothing")
    rows = train_steps + test_steps * n_methods
    disk_bytes = rows * (REQUESTS_CSV_BYTES_PER_ROW + (YAFS_CSV_BYTES_PER_ROW if config.write_yafs_csv else 0))
    memory_bytes = (train_steps + test_steps) * MEMORY_BYTES_PER_STEP
    hours = estimated_seconds(train_steps, rows) / 3600
    if not config.force and (disk_bytes > MAX_DISK_BYTES or memory_bytes > MAX_MEMORY_BYTES):
        raise BudgetError(
            f"{scale}: about {disk_bytes / 1e9:.1f} GB of results and {memory_bytes / 1e9:.1f} GB of "
            f"memory (limits {MAX_DISK_BYTES / 1e9:g} GB and {MAX_MEMORY_BYTES / 1e9:g} GB) and "
            f"about {hours:.1f} h; pass --force to run it anyway"
        )
    if disk_bytes > WARN_DISK_BYTES:
        log.warning("%s will write about %.1f GB into %s", scale, disk_bytes / 1e9, config.out_dir)
    if hours * 3600 > WARN_SECONDS:
        log.warning("%s will take about %.0f min (one process; measured speeds, docs/results.md)",
                    scale, hours * 60)


def estimated_seconds(train_steps: int, rows: int) -> float:
    """Wall time of a run's training and simulations at the measured speeds (one process)."""
    return train_steps * SECONDS_PER_TRAINING_STEP + rows * SECONDS_PER_ROW
