"""Cost of one SafeTail decision and of one training round, at n = 5.

A decision is what a selection does per request: ``encode_state`` + the NumPy forward pass +
argmax (``learner.act`` without exploration). For comparison the same network is timed
through Keras's ``model.predict`` and ``model(x)`` on one row.

Usage::

    python benchmarks/bench_policy.py [--preset paper|tuned] [--use-case 1] [--repeats 20000]

The last line is ``median_decision_us=<number>``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np

from yafs_safetail.edge.published import USE_CASES
from yafs_safetail.methods.safetail import SafeTailLearner, StateScales, encode_state, state_dim
from yafs_safetail.methods.safetail.presets import PRESET_NAMES, get_preset
from yafs_safetail.methods.safetail.spaces import random_observation

N_SERVERS = 5




def per_call_us(fn: Callable[[int], object], repeats: int) -> list[float]:
    """Wall time of each call, µs (one timer pair per call, so the median is per call)."""
    times = []
    clock = time.perf_counter_ns
    for i in range(repeats):
        t0 = clock()
        fn(i)
        times.append((clock() - t0) / 1e3)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="tuned", choices=PRESET_NAMES)
    parser.add_argument("--use-case", type=int, default=1, choices=USE_CASES)
    parser.add_argument("--repeats", type=int, default=20000)
    parser.add_argument("--keras-repeats", type=int, default=200)
    args = parser.parse_args()

    config = get_preset(args.preset, args.use_case)
    scales = StateScales.for_use_case(args.use_case)
    dim = state_dim(N_SERVERS, 0, 2)
    learner = SafeTailLearner(N_SERVERS, dim, config, seed=0)
    model = learner.model
    rng = np.random.default_rng(1)
    observations = [random_observation(rng, N_SERVERS) for _ in range(1000)]
    rows = np.stack([encode_state(o, scales) for o in observations])

    def decide(i: int) -> int:
        return learner.act(encode_state(observations[i % 1000], scales), explore=False)

    def encode_only(i: int) -> np.ndarray:
        return encode_state(observations[i % 1000], scales)

    def keras_call(i: int) -> object:
        return np.asarray(model(rows[i % 1000][None, :], training=False)).argmax()

    def keras_predict(i: int) -> object:
        return model.predict(rows[i % 1000][None, :], verbose=0).argmax()

    for fn in (decide, keras_call, keras_predict):
        for i in range(20):
            fn(i)  # warm-up (tracing, caches)
    decision = statistics.median(per_call_us(decide, args.repeats))
    encode = statistics.median(per_call_us(encode_only, args.repeats))
    call = statistics.median(per_call_us(keras_call, args.keras_repeats))
    predict = statistics.median(per_call_us(keras_predict, max(20, args.keras_repeats // 4)))

    # Training rounds until the buffer is full, then 3 more; time each observe() that trains.
    round_s = []
    env = np.random.default_rng(2)
    n_rounds = -(-config.replay_capacity // config.kappa) + 3
    for _ in range(n_rounds):
        for k in range(config.kappa):
            x = rows[env.integers(1000)]
            a = learner.act(x, explore=True)
            reward = 0.0 if k % 4 == 0 else -0.003 * float(env.random())
            t0 = time.perf_counter()
            trained = learner.observe(x, a, reward)
            if trained:
                round_s.append(time.perf_counter() - t0)
    # The first round traces the train step; steady state = the last 3 rounds (buffer full).
    first_round_s, steady = round_s[0], statistics.median(round_s[-3:])

    print(f"preset={config.name} use_case={config.use_case} n={N_SERVERS} state_dim={dim} "
          f"hidden={config.hidden_widths} actions={learner.n_actions}")
    print(f"encode_state median: {encode:.2f} us")
    print(f"decision (encode_state + NumPy forward + argmax) median: {decision:.2f} us "
          f"over {args.repeats} calls")
    print(f"keras model(x) one row median: {call:.1f} us  (ratio to decision: {call / decision:.0f}x)")
    print(f"keras model.predict one row median: {predict:.1f} us  "
          f"(ratio to decision: {predict / decision:.0f}x)")
    print(f"training round ({config.epochs_per_round} epoch(s), batch {config.batch_size}, "
          f"up to {config.replay_capacity} tuples): first {first_round_s * 1e3:.1f} ms, "
          f"full-buffer median {steady * 1e3:.1f} ms (rows per round: "
          f"{min(config.replay_capacity, learner.n_stored)})")
    print(f"median_decision_us={decision:.2f}")


if __name__ == "__main__":
    main()
