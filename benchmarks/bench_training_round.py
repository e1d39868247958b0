"""What a training round costs, and why runs do not compile it with XLA.

Trains the ``paper`` preset's network (use case 1, n = 5) for ``--rounds`` rounds of 64
minibatch Adam updates on a fixed random replay memory, once as runs do (one TensorFlow graph
call per round, ``network.make_round_updates``) and once compiled with XLA, each in a fresh
process, and prints::

    first_round_s=<graph>  first_round_xla_s=<xla>     (tracing and compiling included)
    round_ms=<graph>       round_xla_ms=<xla>          (median of the later rounds)
    same_weights=<yes|no>  (the two networks' weights bit for bit after the same rounds)

``same_weights=no`` is why runs keep the plain graph: a faster round that changes the weights
changes every results file of every run.

Usage::

    python benchmarks/bench_training_round.py [--rounds 30]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

import numpy as np

STATE_DIM, N_ACTIONS, REPLAY_ROWS = 20, 31, 2500


def train(rounds: int, jit_compile: bool) -> dict[str, object]:
    """Train for ``rounds`` rounds in this process; the timings and a digest of the weights."""
    from yafs_safetail.methods.safetail import network
    from yafs_safetail.methods.safetail.presets import get_preset

    config = get_preset("paper", 1)
    network.enable_determinism(0)
    model = network.build_network(STATE_DIM, N_ACTIONS, config, init_seed=5)
    update = network.make_round_updates(model, jit_compile=jit_compile)
    rng = np.random.default_rng(0)
    states = rng.random((REPLAY_ROWS, STATE_DIM), dtype=np.float32)
    targets = rng.dirichlet(np.ones(N_ACTIONS), REPLAY_ROWS).astype(np.float32)
    times_s = []
    for _ in range(rounds):
        batches = np.stack([rng.choice(REPLAY_ROWS, config.batch_size, replace=False)
                            for _ in range(config.updates_per_round)])
        started = time.perf_counter()
        update(states, targets, batches)
        times_s.append(time.perf_counter() - started)
    weights = b"".join(np.ascontiguousarray(w).tobytes() for w in model.get_weights())
    return {"first_s": times_s[0], "round_s": statistics.median(times_s[1:]), "weights": weights.hex()}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=30, help="rounds per network (default 30)")
    parser.add_argument("--child", choices=("graph", "xla"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.rounds < 2:
        parser.error("--rounds: at least 2 (the first round includes tracing)")
    if args.child:  # one network per process: XLA and op determinism are process-wide states
        print(json.dumps(train(args.rounds, jit_compile=args.child == "xla")))
        return
    measured = {}
    for kind in ("graph", "xla"):
        done = subprocess.run([sys.executable, __file__, "--rounds", str(args.rounds), "--child", kind],
                              capture_output=True, text=True, check=True)
        measured[kind] = json.loads(done.stdout.strip().splitlines()[-1])
    graph, xla = measured["graph"], measured["xla"]
    print(f"first_round_s={graph['first_s']:.2f}  first_round_xla_s={xla['first_s']:.2f}")
    print(f"round_ms={1e3 * graph['round_s']:.1f}  round_xla_ms={1e3 * xla['round_s']:.1f}")
    print(f"same_weights={'yes' if graph['weights'] == xla['weights'] else 'no'}")


if __name__ == "__main__":
    main()
