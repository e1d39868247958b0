"""How far apart two equally good methods' p99 land in one load sweep (run on demand).

    python investigations/bench_sweep_noise.py [--loads 0.5,0.7,0.9] [--seeds 0,1,2,3,4,5] [--requests 20000]

The load sweep's goal compares SafeTail's p99 with the best fixed method's within 5%. This
prints what that margin is made of when nothing differs but chance: Tied against the same tied
request with its ties broken at random instead of by distance (both send to the two servers
with the fewest jobs; the servers are at the topology's distances, so a tie between two of
them is a coin toss either way). Same test world, same arrivals and draws (the sweep's own
setting: UC1, 50 users, FIFO queues, no background tenants). One line per load and seed with
the p99 ratio, then ``max_abs_log_ratio=<x>``: the largest |log(ratio)|, so exp(x) − 1 is the
largest gap chance alone made.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import numpy as np

from yafs_safetail.cli import ArgumentParser, distinct_int_list, load_list, positive_int, run_cli
from yafs_safetail.contention.run import run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.hedging import Tied
from yafs_safetail.methods.registry import method_rng


class TiedCoinToss(Tied):
    """Tied with ties in the servers' jobs broken at random (Tied breaks them by distance)."""

    def choose(self, observation: Observation | None) -> tuple[int, ...]:
        assert observation is not None
        jobs = observation.server_active_users
        # Random keys below 1 only reorder servers with the same number of jobs.
        order = np.argsort(jobs + self.rng.random(jobs.shape[0]), kind="stable")
        return tuple(order[:2].tolist())


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="bench_sweep_noise.py", description=__doc__)
    parser.add_argument("--loads", type=load_list, default=(0.5, 0.7, 0.9), help="offered loads")
    parser.add_argument("--seeds", type=distinct_int_list, default=(0, 1, 2, 3, 4, 5), help="distinct seeds")
    parser.add_argument("--requests", type=positive_int, default=20_000,
                        help="test requests per run (the sweep's at --steps-scale 1)")
    parser.add_argument("--users", type=positive_int, default=50)
    args = parser.parse_args(argv)
    worst = 0.0
    for load in args.loads:
        for seed in args.seeds:
            base = ContentionConfig(use_case=1, users=args.users, seed=seed, queue=True, background=False)
            world = ContentionWorld(replace(base, load=load, phase="test", n_requests=args.requests))
            tied = summarise(run_policy(world, Tied(world.n_servers, method_rng(seed, "Tied"))))
            coin = summarise(run_policy(world, TiedCoinToss(world.n_servers, method_rng(seed, "TiedCoinToss"))))
            ratio = float(coin["p99_s"]) / float(tied["p99_s"])
            worst = max(worst, abs(math.log(ratio)))
            print(f"load={load:g} seed={seed} requests={args.requests} tied_p99_s={tied['p99_s']:.3f} "
                  f"coin_toss_p99_s={coin['p99_s']:.3f} ratio={ratio:.3f}", flush=True)
    print(f"max_abs_log_ratio={worst:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
