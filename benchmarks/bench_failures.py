"""The exact result the edge world's failures must reproduce: all k copies lost with probability p^k.

Each server alternates exponential up and down times and starts in its stationary state, so at
any instant it is down with probability p = MTTR / (MTTF + MTTR), independently of the others.
A copy is lost when its server is down on arrival or fails before its compute ends; when
compute times are tiny next to the MTTF the second case is negligible, so each copy is lost
with probability p, and a request whose k copies go to k distinct servers loses all of them
with probability p^k (end_reason ``all_lost``).

The benchmark runs the edge simulator itself (``sim.runner.simulate``) with Rand-k, k = 1..5,
on one UC1 test world drawn with:

- p = 0.9 (``--probability``), MTTF = 1,000 s, MTTR = p/(1-p) x MTTF = 9,000 s: a UC1 compute
  time (about a second) is 1e-3 of the MTTF, so a copy up on arrival fails during its compute
  with probability about 1e-3 x (1 - p) / p ~ 1e-4 relative to p: a bias of ~5e-4 on p^5,
  far inside the bound;
- one request every 25,000 s: a server's state decorrelates at rate 1/MTTF + 1/MTTR, so two
  consecutive requests see states correlated by exp(-25,000 x 1.11e-3) ~ 1e-12: independent;
- no background load (``load_peak_users`` = 0): no copy is refused, so "every copy not refused
  was lost" is "all k copies lost";
- the default time-out (the world's worst-case live copy): a live copy always replies within it.

Statistics: the share of N requests with all k copies lost is binomial, so its relative error
has standard deviation sqrt((1 - p^k) / (N p^k)). With p = 0.9 and N = 30,000 this is largest at
k = 5: sqrt(0.41 / (0.59 x 30,000)) = 0.0048, so a relative error of 0.02 is 4.1 standard
deviations there (and more for k < 5): max_rel_error <= 0.02 fails by chance about once in
10,000 seeds. The printed interval is the share's 95% Wilson interval; p^k should lie inside
it about 95% of the time for each k.

Usage::

    python benchmarks/bench_failures.py [--requests 30000] [--probability 0.9] [--seed 7]

Prints one line per k and ``max_rel_error=``; exit status 1 when it exceeds ``--bound``.
Takes about a minute on one core.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time

import numpy as np

from yafs_safetail.edge.failures import END_ALL_LOST, FailureSettings
from yafs_safetail.methods.baselines import RandX
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.sim.runner import simulate
from yafs_safetail.worlds.recipe import world_recipe

#: Mean time to failure: a thousand times a UC1 compute time (see the module docstring).
MTTF_S = 1_000.0
#: Time between requests: consecutive requests see independent server states.
STEP_INTERVAL_S = 25_000.0
#: z of a two-sided 95% interval.
Z_95 = 1.959963984540054


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of a binomial share."""
    share = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (share + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(share * (1 - share) / trials + z * z / (4 * trials * trials)) / denominator
    return centre - half, centre + half


def all_lost_shares(n_requests: int, probability: float, seed: int) -> dict[int, float]:
    """Per k = 1..n, the share of Rand-k's requests with every copy lost, on one world."""
    mttr_s = MTTF_S * probability / (1.0 - probability)
    failures = FailureSettings(mttf_s=MTTF_S, mttr_s=mttr_s)
    recipe = world_recipe(ExperimentConfig(use_case=1, load_peak_users=0.0, step_interval_s=STEP_INTERVAL_S))
    recipe = dataclasses.replace(recipe, failures=failures, test_steps=n_requests)
    world = recipe.make_world("test", seed)
    shares = {}
    for k in range(1, world.n_servers + 1):
        records = simulate(world, RandX(world.n_servers, np.random.default_rng(seed + k), k),
                           step_interval_s=STEP_INTERVAL_S)
        if any(record.refused for record in records):
            raise RuntimeError("a copy was refused: the benchmark needs a world without load")
        shares[k] = sum(record.end_reason == END_ALL_LOST for record in records) / len(records)
    return shares


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--requests", type=int, default=30_000, help="requests per k (default 30000)")
    parser.add_argument("--probability", type=float, default=0.9,
                        help="each server's stationary down probability p (default 0.9)")
    parser.add_argument("--seed", type=int, default=7, help="the world's and the policies' seed (default 7)")
    parser.add_argument("--bound", type=float, default=0.02,
                        help="the largest relative error accepted (default 0.02)")
    args = parser.parse_args(argv)
    if not 0 < args.probability < 1 or args.requests < 1:
        parser.error("--probability must be in (0, 1) and --requests >= 1")
    started = time.perf_counter()
    shares = all_lost_shares(args.requests, args.probability, args.seed)
    print(f"p={args.probability} requests={args.requests} mttf_s={MTTF_S:g} "
          f"step_interval_s={STEP_INTERVAL_S:g} seed={args.seed}")
    print(f"{'k':>2} {'share':>8} {'p^k':>8} {'95% interval':>20} {'rel_error':>9}")
    worst = 0.0
    for k, share in shares.items():
        exact = args.probability ** k
        low, high = wilson_interval(round(share * args.requests), args.requests)
        relative = abs(share - exact) / exact
        worst = max(worst, relative)
        inside = "p^k inside" if low <= exact <= high else "p^k outside"
        print(f"{k:>2} {share:8.5f} {exact:8.5f} [{low:8.5f}, {high:8.5f}] {relative:9.5f}  {inside}")
    print(f"wall_s={time.perf_counter() - started:.1f}")
    print(f"max_rel_error={worst:.5f}")
    return 0 if worst <= args.bound else 1


if __name__ == "__main__":
    sys.exit(main())
