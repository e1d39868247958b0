"""The contention world with failing servers: success rate, p99 and energy per request of a few
methods at a few failure probabilities (docs/contention.md, "Failures and energy").

    python tables/contention_failures_table.py [--requests N] [--seed S] [--load L]
        [--probabilities 0,0.1] [--methods A,B] [--no-background] [--mttr-s S]

Prints a markdown table; every figure in that docs section comes from it.
"""

from __future__ import annotations

import argparse

import numpy as np

from yafs_safetail.contention.run import run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.edge.failures import FailureSettings
from yafs_safetail.methods.registry import make_baseline

METHODS = ("MinLoad-1", "Rand-1", "Rand-2", "Rand-3", "Hedge", "Tied", "Oracle")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=6000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--load", type=float, default=0.3)
    parser.add_argument("--probabilities", default="0,0.1", help="each server's stationary down probability")
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--no-background", action="store_true", help="no background tenants")
    parser.add_argument("--mttr-s", type=float, default=60.0, help="mean time to repair")
    args = parser.parse_args()
    print("| failure probability | method | success rate | all refused | all lost | timeout | p50 (s) | "
          "p99 (s) | energy per request (J) | mean copies |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for probability in (float(p) for p in args.probabilities.split(",")):
        world = ContentionWorld(ContentionConfig(
            users=20, n_requests=args.requests, seed=args.seed, load=args.load, background=not args.no_background,
            failures=FailureSettings.for_unavailability(probability, mttr_s=args.mttr_s)))
        for name in args.methods.split(","):
            row = summarise(run_policy(world, make_baseline(name, world.n_servers,
                                                            np.random.default_rng(args.seed))))
            print(f"| {probability} | {name} | {row['success_rate']:.3f} | {row['share_all_refused']:.3f} | "
                  f"{row['share_all_lost']:.3f} | {row['share_timeout']:.3f} | {row['p50_s']:.2f} | "
                  f"{row['p99_s']:.2f} | {row['energy_j_per_request']:.1f} | "
                  f"{row['mean_n_selected']:.2f} |")
        if probability:
            downs = [1.0 - world.down_intervals.up_fraction(i, float(world.emit_s[-1]))
                     for i in range(world.n_servers)]
            print(f"\nservers' measured down fractions: {', '.join(f'{d:.3f}' for d in downs)}")
            print(f"time-out: {world.timeout_s:.2f} s; on-device fallback: {world.fallback_latency_s:.2f} s; "
                  f"per-process power {world.config.energy.server.per_process_w:.2f} W")


if __name__ == "__main__":
    main()
