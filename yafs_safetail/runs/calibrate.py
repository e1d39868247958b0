"""Fit the unpublished world parameters without the learner (docs/calibration.md, rule 1).

The paper never published how its load trace maps to server load, how a server's bandwidth is
shared, or how long the on-device fallback takes (yafs_safetail.edge.calibration lists each
parameter with its rule). This module fits them, one value each for all three use cases, to
what the paper's use-case-1 numbers imply about the world alone: the latency of Rand-1, MinLoad-1
and MinProp-1 over Oracle's at p50, p90, p95 and p99 (:func:`implied_over_oracle`). SafeTail is
not in the objective, so the fit does not depend on how a network happened to train, and it
needs no TensorFlow.

The flow reads top to bottom in :func:`calibrate`:

1. every point of a fixed grid (:data:`GRID`) is a candidate world;
2. for each calibration seed, UC1's test world is drawn with the candidate's settings and each
   method's latency is read from the world's per-copy table (:func:`method_latencies_s`; with
   one request a minute every copy has ended before the next request, so this equals the
   simulation, which a test checks);
3. the objective is the mean over seeds and the twelve cells of |log(ours / implied)|;
4. the lowest objective wins, ties by grid order (a parameter the tied candidates differ in is
   recorded as unidentified); every candidate goes to ``evaluations.csv``, the winner with its
   provenance to ``calibration.json``.

A grid rather than a search path: the same candidates are scored on any machine, so a rerun
lands on the same parameters unless two candidates tie to the last digits (the provenance
gives the margin to the runner-up).
"""

from __future__ import annotations

import concurrent.futures
import datetime
import functools
import itertools
import json
import logging
import math
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
    WorldSettings,
    calibrated_settings,
    seed_set,
)
from yafs_safetail.edge.inputs import load_inputs, load_scenario_for
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS, EdgeWorld, build_world
from yafs_safetail.methods.baselines import candidates_of
from yafs_safetail.methods.registry import ORACLE, SAFETAIL, make_baseline, method_rng
from yafs_safetail.results.files import PERCENTILES
from yafs_safetail.results.paper import CALIBRATION_RATIOS, PaperRatio, paper_speedup
from yafs_safetail.runs.workers import end_with_parent

#: The single-server baselines whose latency over Oracle's the fit matches.
X1_BASELINES = ("Rand-1", "MinLoad-1", "MinProp-1")
#: The candidates: every combination, in this order (ties go to the earlier one).
GRID: Mapping[str, tuple[Any, ...]] = {
    "load_start": LOAD_STARTS,
    "load_peak_users": tuple(2.5 + 0.25 * i for i in range(11)),        # 2.5 .. 5.0
    "bandwidth_share_exponent": tuple(0.25 * i for i in range(9)),      # 0 .. 2
    "fallback_compute_multiple": (4.0, 8.0, 16.0),
}
#: Use case 1's test phase: 20·β requests (paper §V).
TEST_STEPS = 4000
EVALUATIONS_FILE = "evaluations.csv"
RESULT_FILE = "calibration.json"


class CalibrationRunError(ValueError):
    """A bad calibration setting (one line naming it)."""


def implied_over_oracle() -> dict[tuple[str, int], float]:
    """What the paper's use-case-1 numbers imply about the world alone: each x = 1 baseline's
    latency over Oracle's at each percentile.

    latency(b) / latency(Oracle) = [latency(b) / latency(SafeTail)] · [latency(SafeTail) /
    latency(Oracle)], i.e. SafeTail's published speed-up over b divided by its published
    speed-up over Oracle (facts.md's table; no learner involved once the numbers are published).
    """
    implied = {}
    for baseline in X1_BASELINES:
        for percentile in PERCENTILES:
            over_baseline = paper_speedup(1, SAFETAIL, baseline, percentile)
            over_oracle = paper_speedup(1, SAFETAIL, ORACLE, percentile)
            assert over_baseline is not None and over_oracle is not None
            implied[(baseline, percentile)] = over_baseline / over_oracle
    return implied


def consumed_numbers() -> tuple[PaperRatio, ...]:
    """The published numbers the fit consumes (the calibration subset): UC1's ratios of
    SafeTail against the x = 1 baselines and against Oracle."""
    return CALIBRATION_RATIOS


def cell_key(method: str, percentile: int) -> str:
    return f"{method}/Oracle/p{percentile}"


def grid_candidates(grid: Mapping[str, Sequence[Any]] = GRID) -> list[dict[str, Any]]:
    """Every point of ``grid``, in order."""
    names = list(grid)
    return [dict(zip(names, values, strict=True)) for values in itertools.product(*grid.values())]


def settings_for(candidate: Mapping[str, Any]) -> WorldSettings:
    """The world of a candidate: the fitted parameters, the readings, ν by the knee rule."""
    readings = dict(CALIBRATED_READINGS, load_start=candidate["load_start"])
    return calibrated_settings(candidate, readings)


@dataclass(frozen=True)
class SeedChoices:
    """The world-independent draws of the baselines' own generators for one seed.

    Rand-1's choices, MinLoad-1's tie-break numbers (the paper's text) and MinLoad-1's and
    MinProp-1's drawn candidates (the original code's reading) come from the methods'
    generators (``method_rng``), which never read the world, so they are drawn once per seed
    and reused for every candidate world (common random numbers across candidates).
    """

    rand_server: np.ndarray
    minload_tiebreak: np.ndarray
    minload_candidates: np.ndarray
    minprop_candidates: np.ndarray


def _drawn_candidates(seed: int, method: str, n_servers: int, n_steps: int) -> np.ndarray:
    """The servers the original code's reading of ``method`` draws for each request, in order."""
    k = candidates_of("original-code", 1, n_servers)
    assert k is not None
    rng = method_rng(seed, method)
    return np.array([rng.choice(n_servers, size=k, replace=False) for _ in range(n_steps)], dtype=np.int64)


def seed_choices(seed: int, n_servers: int, n_steps: int) -> SeedChoices:
    """Draw what the real Rand-1, MinLoad-1 and MinProp-1 draw, in the order they draw it."""
    rand = make_baseline("Rand-1", n_servers, method_rng(seed, "Rand-1"))
    servers = np.array([rand.choose(None)[0] for _ in range(n_steps)], dtype=np.int64)
    # MinLoad-x of the paper's text draws one number per server per request (its tie break).
    tiebreak = method_rng(seed, "MinLoad-1").random((n_steps, n_servers))
    return SeedChoices(servers, tiebreak, _drawn_candidates(seed, "MinLoad-1", n_servers, n_steps),
                       _drawn_candidates(seed, "MinProp-1", n_servers, n_steps))


def method_latencies_s(world: EdgeWorld, choices: SeedChoices) -> dict[str, np.ndarray]:
    """Oracle's and the x = 1 baselines' latency per request of ``world``.

    Valid when every copy has ended before the next request (the default one request a minute):
    then the active users a request meets are the background users, and a copy's latency is
    ``world.copy_latency_table_s()``. A refused copy (``inf``) leaves the on-device fallback.
    """
    table = world.copy_latency_table_s()
    fallback_s = world.fallback_latency_s
    steps = np.arange(world.n_steps)

    def single(servers: np.ndarray) -> np.ndarray:
        latency = table[steps, servers]
        return np.where(np.isfinite(latency), latency, fallback_s)

    oracle = table.min(axis=1)
    if world.settings.baseline_reading == "original-code":
        # The first of the drawn servers with the fewest active users / the lowest median
        # propagation (argmin keeps the first of equals, as the policies' stable sort does).
        drawn_load = world.background_users[steps[:, None], choices.minload_candidates]
        minload = choices.minload_candidates[steps, np.argmin(drawn_load, axis=1)]
        drawn_propagation = world.median_propagation_s[choices.minprop_candidates]
        minprop = choices.minprop_candidates[steps, np.argmin(drawn_propagation, axis=1)]
    else:
        # MinLoad: fewest active users, ties to the smallest tie-break number (integer loads,
        # draws in [0, 1): the sum orders exactly as the policy's lexsort does).
        minload = np.argmin(world.background_users + choices.minload_tiebreak, axis=1)
        # MinProp: the smallest median propagation, ties by index (a stable argmin).
        minprop = np.full(world.n_steps, int(np.argmin(world.median_propagation_s)))
    return {
        ORACLE: np.where(np.isfinite(oracle), oracle, fallback_s),
        "Rand-1": single(choices.rand_server),
        "MinLoad-1": single(minload),
        "MinProp-1": single(minprop),
    }


@dataclass
class Evaluation:
    """One candidate's score over the calibration seeds."""

    parameters: dict[str, Any]
    objective: float
    within_20: float
    ratios: dict[str, float] = field(default_factory=dict)
    fallback_share: dict[str, float] = field(default_factory=dict)

    def row(self) -> dict[str, Any]:
        return {**self.parameters, "objective": self.objective, "within_20": self.within_20,
                **{f"ratio {k}": v for k, v in self.ratios.items()},
                **{f"fallback {k}": v for k, v in self.fallback_share.items()}}


def objective(per_seed: Sequence[Mapping[str, float]]) -> tuple[float, float, dict[str, float]]:
    """(mean |log(ours / implied)|, share within ±20%, mean ratio per cell) over seeds and the
    twelve cells; ``per_seed`` maps :func:`cell_key` to our latency ratio over Oracle's."""
    implied = implied_over_oracle()
    errors, hits = [], []
    for ratios in per_seed:
        for (method, percentile), paper in implied.items():
            ours = ratios[cell_key(method, percentile)]
            errors.append(abs(math.log(ours / paper)) if ours > 0 else math.inf)
            hits.append(abs(ours / paper - 1.0) <= 0.2)
    means = {cell_key(m, p): float(np.mean([s[cell_key(m, p)] for s in per_seed])) for m, p in implied}
    return float(np.mean(errors)), float(np.mean(hits)), means


@functools.lru_cache(maxsize=4)
def _scenario(topology: str, placement: str) -> tuple[Any, Any, Any]:
    use_case = get_use_case(1)
    inputs = load_inputs(use_case)
    return use_case, inputs, load_scenario_for(inputs, Path(topology), Path(placement))


@functools.lru_cache(maxsize=64)
def _choices(seed: int, n_servers: int, n_steps: int) -> SeedChoices:
    return seed_choices(seed, n_servers, n_steps)


def score(candidate: Mapping[str, Any], seeds: Sequence[int], n_steps: int = TEST_STEPS,
          topology: Path = DEFAULT_TOPOLOGY, placement: Path = DEFAULT_PLACEMENT) -> Evaluation:
    """A candidate's objective over ``seeds`` (each seed's UC1 test world)."""
    use_case, inputs, scenario = _scenario(str(topology), str(placement))
    settings = settings_for(candidate)
    per_seed, fallbacks = [], []
    for seed in seeds:
        world = build_world(scenario, use_case, inputs, n_steps, seed=seed, phase="test",
                            episode_steps=DEFAULT_EPISODE_STEPS, settings=settings)
        latencies = method_latencies_s(world, _choices(seed, world.n_servers, n_steps))
        oracle = np.percentile(latencies[ORACLE], PERCENTILES)
        per_seed.append({cell_key(m, p): float(q / o) for m in X1_BASELINES
                         for p, q, o in zip(PERCENTILES, np.percentile(latencies[m], PERCENTILES),
                                            oracle, strict=True)})
        fallbacks.append({m: float(np.mean(latencies[m] == world.fallback_latency_s))
                          for m in (ORACLE, *X1_BASELINES)})
    value, within, means = objective(per_seed)
    share = {m: float(np.mean([f[m] for f in fallbacks])) for m in (ORACLE, *X1_BASELINES)}
    return Evaluation(dict(candidate), value, within, means, share)


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
    ranked = sorted(range(len(evaluations)), key=lambda i: (evaluations[i].objective, i))
    best = evaluations[ranked[0]]
    # Candidates that score exactly as the best differ only in parameters the objective cannot
    # see (e.g. the fallback multiple where no server ever refuses): those are unidentified,
    # and the grid's order, not the data, chose their value. The runner-up is the best other score.
    tied = [e for e in evaluations if e.objective == best.objective]
    unidentified = [name for name in config.grid if len({e.parameters[name] for e in tied}) > 1]
    runner_up = next((evaluations[i] for i in ranked if evaluations[i].objective > best.objective), best)
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
            "objective_value": round(best.objective, 6),
            "runner_up_objective": round(runner_up.objective, 6),
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
