"""How the contention world scales: 1,000 users, 10^4 to 10^6 requests (run on demand).

    python benchmarks/bench_multiuser.py [--sizes 10000,100000,1000000] [--users 1000]
        [--method MinLoad-2] [--load 0.5] [--queue]

Each size runs in a fresh process (so its peak memory is its own): use case 1, the paper
topology, background tenants on, cancellation on, the method's every decision made from ω^t.
Prints one line per size, ``requests=<N> seconds=<t> peak_mb=<m>`` (seconds: the simulation,
without building the inputs), and the cost per request, which must stay flat (linear growth).
"""

from __future__ import annotations

import multiprocessing
import resource
import sys
import time

import numpy as np

from yafs_safetail.cli import (
    ArgumentParser,
    distinct_int_list,
    positive_float,
    positive_int,
    run_cli,
)


def _one_size(n_requests: int, users: int, method: str, load: float, queue: bool, seed: int) -> tuple[float, float]:
    from yafs_safetail.contention.run import run_policy
    from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
    from yafs_safetail.methods.registry import make_baseline

    world = ContentionWorld(ContentionConfig(n_requests=n_requests, users=users, load=load, queue=queue,
                                             seed=seed))
    policy = make_baseline(method, world.n_servers, np.random.default_rng(seed))
    started = time.perf_counter()
    run = run_policy(world, policy)
    seconds = time.perf_counter() - started
    assert np.isfinite(run.result.latency_s).all()
    return seconds, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="bench_multiuser.py", description=__doc__)
    parser.add_argument("--sizes", type=distinct_int_list, default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--users", type=positive_int, default=1000)
    parser.add_argument("--method", default="MinLoad-2")
    parser.add_argument("--load", type=positive_float, default=0.5)
    parser.add_argument("--queue", action="store_true", help="FIFO queues instead of refusal")
    parser.add_argument("--seed", type=positive_int, default=1)
    args = parser.parse_args(argv)
    context = multiprocessing.get_context("spawn")
    print(f"users={args.users} method={args.method} load={args.load} queue={args.queue}", flush=True)
    for size in args.sizes:
        with context.Pool(1) as pool:
            seconds, peak_mb = pool.apply(_one_size, (size, args.users, args.method, args.load, args.queue,
                                                      args.seed))
        print(f"requests={size} seconds={seconds:.1f} peak_mb={peak_mb:.0f} "
              f"us_per_request={1e6 * seconds / size:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
