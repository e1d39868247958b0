"""The contention engine against exact queueing results (run on demand).

    python benchmarks/bench_queueing.py [--requests 400000] [--servers 5] [--seed 0]

Stripped configuration (docs/contention.md): exponential service of rate μ = 1, FIFO queues, no
network delay, instantaneous cancellation. Random single dispatch must match k M/M/1 queues,
E[T] = 1/(μ − λ/k); send-to-all with cancel-on-complete one M/M/1 of rate kμ, E[T] = 1/(kμ − λ).
Prints one line per case and utilisation, then ``max_rel_error=<x>`` (the goal: below 0.02).
"""

from __future__ import annotations

import sys
import time

from yafs_safetail.cli import ArgumentParser, non_negative_int, positive_int, run_cli
from yafs_safetail.contention.queueing import QUEUEING_CASES, simulate_case

UTILISATIONS = (0.2, 0.5, 0.8)


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="bench_queueing.py", description=__doc__)
    parser.add_argument("--requests", type=positive_int, default=400_000, help="requests per case")
    parser.add_argument("--servers", type=positive_int, default=5, help="k")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    args = parser.parse_args(argv)
    worst = 0.0
    for case in QUEUEING_CASES:
        for utilisation in UTILISATIONS:
            started = time.perf_counter()
            run = simulate_case(case, args.servers, 1.0, utilisation, args.requests, args.seed)
            worst = max(worst, run.rel_error)
            print(f"case={case} k={args.servers} utilisation={utilisation} requests={args.requests} "
                  f"simulated_mean_s={run.simulated_mean_s:.4f} theory_mean_s={run.theory_mean_s:.4f} "
                  f"rel_error={run.rel_error:.4f} seconds={time.perf_counter() - started:.1f}", flush=True)
    print(f"max_rel_error={worst:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
