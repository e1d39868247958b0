"""The learner-free fit score the world is fitted to (docs/calibration.md, rule 1, calls it the
objective; the files keep that name).

What the paper's use-case-1 numbers imply about the world alone (:func:`implied_over_oracle`:
Rand-1's, MinLoad-1's and MinProp-1's latency over Oracle's at p50, p90, p95 and p99), and how
far a candidate world is from it (:func:`score`): for each calibration seed, UC1's test world
is drawn with the candidate's settings and each method's latency is read from the world's
per-copy table (:func:`method_latencies_s`; with one request a minute every copy has ended
before the next request, so this equals the simulation, which a test checks); the fit score is
the mean over seeds and the twelve cells of |log(ours / implied)| (:func:`fit_score`). No
SafeTail, no TensorFlow. ``runs.calibrate`` searches its grid with it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from yafs_safetail.edge.calibration import CALIBRATED_READINGS, WorldSettings, calibrated_settings
from yafs_safetail.edge.inputs import load_inputs, load_scenario_for
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS, EdgeWorld, build_world
from yafs_safetail.methods.baselines import candidates_of
from yafs_safetail.methods.registry import ORACLE, SAFETAIL, make_baseline, method_rng
from yafs_safetail.results.files import PERCENTILES
from yafs_safetail.results.paper import CALIBRATION_RATIOS, PaperRatio, paper_speedup

#: The single-server baselines whose latency over Oracle's the fit matches.
X1_BASELINES = ("Rand-1", "MinLoad-1", "MinProp-1")
#: Use case 1's test phase: 20·β requests (paper §V).
TEST_STEPS = 4000


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
    fit_score: float
    within_20: float
    ratios: dict[str, float] = field(default_factory=dict)
    fallback_share: dict[str, float] = field(default_factory=dict)

    def row(self) -> dict[str, Any]:
        # evaluations.csv's column keeps the name users read: "objective".
        return {**self.parameters, "objective": self.fit_score, "within_20": self.within_20,
                **{f"ratio {k}": v for k, v in self.ratios.items()},
                **{f"fallback {k}": v for k, v in self.fallback_share.items()}}


def fit_score(per_seed: Sequence[Mapping[str, float]]) -> tuple[float, float, dict[str, float]]:
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
    """A candidate's fit score over ``seeds`` (each seed's UC1 test world)."""
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
    value, within, means = fit_score(per_seed)
    share = {m: float(np.mean([f[m] for f in fallbacks])) for m in (ORACLE, *X1_BASELINES)}
    return Evaluation(dict(candidate), value, within, means, share)
