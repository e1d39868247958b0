"""Fit the unpublished world parameters without the learner (docs/calibration.md, rule 1).

The paper never published how its load trace maps to server load, how a server's bandwidth is
shared, or how long the on-device fallback takes (yafs_safetail.edge.calibration lists each
parameter with its rule). This module fits them, one value each for all three use cases, to
what the paper's use-case-1 numbers imply about the world alone: the latency of Rand-1, MinLoad-1
and MinProp-1 over Oracle's at p50, p90, p95 and p99 (:func:`implied_over_oracle`). SafeTail is
not in the fit score, so the fit does not depend on how a network happened to train, and it
needs no TensorFlow.

The flow reads top to bottom in :func:`calibrate`:

1. every point of a fixed grid (:data:`GRID`) is a candidate world;
2. each is scored on the calibration seeds by the learner-free fit score (``runs.world_fit``:
   UC1's test world drawn with the candidate's settings, each method's latency read from the
   world's per-copy table);
3. the fit score (docs/calibration.md and the files: the objective) is the mean over seeds and
   the twelve cells of |log(ours / implied)|;
4. the lowest fit score wins, ties by grid order (a parameter the tied candidates differ in is
   recorded as unidentified); every candidate goes to ``evaluations.csv``, the winner with its
   provenance to ``calibration.json``.

A grid rather than a search path: the same candidates are scored on any machine, so a rerun
lands on the same parameters unless two candidates tie to the last digits (the provenance
gives the margin to the runner-up).
"""

from __future__ import annotations

import concurrent.futures
import datetime
import itertools
import json
import logging
import multiprocessing
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import yafs_safetail
from yafs_safetail import results, versions
from yafs_safetail.edge.calibration import (
    CALIBRATED_PARAMETERS,
    CALIBRATED_READINGS,
    CALIBRATION_FILE,
    LOAD_STARTS,
    seed_set,
)
from yafs_safetail.runs.workers import end_with_parent
from yafs_safetail.runs.world_fit import (
    TEST_STEPS,
    Evaluation,
    cell_key,
    consumed_numbers,
    implied_over_oracle,
    score,
)

#: The candidates: every combination, in this order (ties go to the earlier one).
GRID: Mapping[str, tuple[Any, ...]] = {
    "load_start": LOAD_STARTS,
    "load_peak_users": tuple(2.5 + 0.25 * i for i in range(11)),        # 2.5 .. 5.0
    "bandwidth_share_exponent": tuple(0.25 * i for i in range(9)),      # 0 .. 2
    "fallback_compute_multiple": (4.0, 8.0, 16.0),
}
EVALUATIONS_FILE = "evaluations.csv"
RESULT_FILE = "calibration.json"


class CalibrationRunError(ValueError):
    """A bad calibration setting (one line naming it)."""


def grid_candidates(grid: Mapping[str, Sequence[Any]] = GRID) -> list[dict[str, Any]]:
    """Every point of ``grid``, in order."""
    names = list(grid)
    return [dict(zip(names, values, strict=True)) for values in itertools.product(*grid.values())]



@dataclass(frozen=True)
class CalibrationConfig:
    """What one calibration depends on.

    Attributes:
        seeds: world-calibration seeds (default: ``seed_sets.json``), distinct.
        grid: the candidates' values per parameter (default :data:`GRID`).
        workers: processes scoring candidates in parallel (the result does not depend on it).
        out_dir: where ``evaluations.csv`` and ``calibration.json`` go.
        apply: also install the result as the package's calibration file.
        command: the command line, recorded in the provenance.
    """

    seeds: tuple[int, ...] = field(default_factory=lambda: tuple(seed_set("world_calibration")))
    grid: Mapping[str, tuple[Any, ...]] = field(default_factory=lambda: dict(GRID))
    workers: int = 2
    out_dir: Path = Path("results/calibration")
    apply: bool = False
    command: str = ""


def read_grid(path: Path) -> dict[str, tuple[Any, ...]]:
    """A grid from a JSON file mapping each parameter of :data:`GRID` to a list of values.

    Raises:
        CalibrationRunError: an unreadable file or a missing, unknown or empty parameter.
    """
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CalibrationRunError(f"{path}: not a readable JSON file ({error})") from None
    if not isinstance(data, dict):
        raise CalibrationRunError(f"{path}: expected a JSON object")
    for name in GRID:
        if not isinstance(data.get(name), list) or not data[name]:
            raise CalibrationRunError(f"{path}: {name}: expected a non-empty list of values")
    unknown = sorted(set(data) - set(GRID))
    if unknown:
        raise CalibrationRunError(f"{path}: {unknown[0]}: not a calibrated parameter; valid: {', '.join(GRID)}")
    return {name: tuple(data[name]) for name in GRID}


def check_calibration_config(config: CalibrationConfig) -> None:
    if not config.seeds or len(set(config.seeds)) != len(config.seeds):
        raise CalibrationRunError(f"--seeds: give distinct seeds, got {list(config.seeds)}")
    if set(config.grid) != set(GRID):
        raise CalibrationRunError(f"grid: expected the parameters {sorted(GRID)}, got {sorted(config.grid)}")
    for name, values in config.grid.items():
        if not values:
            raise CalibrationRunError(f"grid: {name} has no values")
        for value in values:
            if name == "load_start":
                ok = value in LOAD_STARTS
                valid = ", ".join(LOAD_STARTS)
            else:
                low, high, _ = CALIBRATED_PARAMETERS[name]
                ok = (isinstance(value, float | int) and not isinstance(value, bool)
                      and low <= value <= high)
                valid = f"{low:g}..{high:g}"
            if not ok:
                raise CalibrationRunError(f"grid: {name}: {value!r} is outside {valid}")


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parents[1],
                             capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() or "unknown"


def _score_chunk(candidates: Sequence[dict[str, Any]], seeds: tuple[int, ...]) -> list[Evaluation]:
    return [score(c, seeds) for c in candidates]


def calibrate(config: CalibrationConfig, log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the calibration; returns the contents of ``calibration.json`` (also written).

    ``log`` takes each progress line (default: this module's logger at INFO).
    """
    if log is None:
        log = logging.getLogger(__name__).info
    check_calibration_config(config)
    started = time.perf_counter()
    candidates = grid_candidates(config.grid)
    log(f"{len(candidates)} candidates x {len(config.seeds)} seeds")
    # Contiguous chunks, gathered in order: the result is the same for any number of workers.
    n_chunks = max(1, min(len(candidates), 8 * config.workers))
    chunks = [list(c) for c in np.array_split(np.arange(len(candidates)), n_chunks)]
    evaluations: list[Evaluation] = []
    if config.workers == 1:
        for chunk in chunks:
            evaluations += _score_chunk([candidates[i] for i in chunk], config.seeds)
    else:
        context = multiprocessing.get_context("spawn")
        # end_with_parent: a killed calibration leaves no worker process behind.
        with concurrent.futures.ProcessPoolExecutor(config.workers, mp_context=context,
                                                    initializer=end_with_parent) as pool:
            futures = [pool.submit(_score_chunk, [candidates[i] for i in chunk], config.seeds)
                       for chunk in chunks]
            for done, future in enumerate(futures, 1):
                evaluations += future.result()
                log(f"scored {len(evaluations)} of {len(candidates)} candidates ({done}/{len(futures)})")
    ranked = sorted(range(len(evaluations)), key=lambda i: (evaluations[i].fit_score, i))
    best = evaluations[ranked[0]]
    # Candidates that score exactly as the best differ only in parameters the fit score cannot
    # see (e.g. the fallback multiple where no server ever refuses): those are unidentified,
    # and the grid's order, not the data, chose their value. The runner-up is the best other score.
    tied = [e for e in evaluations if e.fit_score == best.fit_score]
    unidentified = [name for name in config.grid if len({e.parameters[name] for e in tied}) > 1]
    runner_up = next((evaluations[i] for i in ranked if evaluations[i].fit_score > best.fit_score), best)
    config.out_dir.mkdir(parents=True, exist_ok=True)
    trace = pd.DataFrame([e.row() for e in evaluations])
    results.write_text_atomic(config.out_dir / EVALUATIONS_FILE, trace.to_csv(index=False))
    document = {
        "parameters": {name: best.parameters[name] for name in CALIBRATED_PARAMETERS},
        "readings": dict(CALIBRATED_READINGS, load_start=best.parameters["load_start"]),
        "provenance": {
            "rule": "docs/calibration.md, rule 1: learner-free, every grid point, lowest objective",
            "consumed": [f"{r.method}/{r.reference}/p{r.percentile} (use case 1, paper {r.speedup})"
                         for r in consumed_numbers()],
            "implied_over_oracle": {cell_key(m, p): round(v, 4)
                                    for (m, p), v in implied_over_oracle().items()},
            "objective": "mean over seeds and the twelve cells of |log(ours / implied)|",
            "objective_value": round(best.fit_score, 6),
            "runner_up_objective": round(runner_up.fit_score, 6),
            "runner_up": runner_up.parameters,
            "unidentified": unidentified,
            "within_20_percent": round(best.within_20, 4),
            "ratios_mean_over_seeds": {k: round(v, 4) for k, v in best.ratios.items()},
            "fallback_share": {k: round(v, 4) for k, v in best.fallback_share.items()},
            "seeds": list(config.seeds),
            "test_steps": TEST_STEPS,
            "grid": {k: list(v) for k, v in config.grid.items()},
            "evaluations": len(evaluations),
            "date": datetime.date.today().isoformat(),
            "command": config.command,
            "package_version": yafs_safetail.__version__,
            **versions.run_json_fields(),
            "git_commit": _git_commit(),
            "wall_s": round(time.perf_counter() - started, 1),
        },
    }
    text = json.dumps(document, indent=2) + "\n"
    results.write_text_atomic(config.out_dir / RESULT_FILE, text)
    if config.apply:
        results.write_text_atomic(CALIBRATION_FILE, text)
    return document
