"""Plug in your own policy and compare it with the baselines on the same requests.

``NearestFree`` (nearest_free.py, ten lines) sends each request to the nearest server that still
has room, and a second copy to the next nearest one when the first is busy. It sees exactly
what SafeTail sees (the Observation, ω^t) and runs on exactly the same requests as the
baselines (common random numbers); it lands between MinProp-1 (always one copy, to the nearest
server) and MinProp-2 (always two). The same class can join a full experiment:
``yafs-safetail run --uc 1 --method examples/custom_policy/nearest_free.py:NearestFree``.

    python examples/custom_policy/main.py --uc 1 --steps 400
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from nearest_free import NearestFree

from yafs_safetail.edge.calibration import world_settings
from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, load_inputs
from yafs_safetail.methods import make_baseline
from yafs_safetail.sim.runner import simulate

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, default=1)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    use_case = get_use_case(args.uc)
    scenario = load_scenario(ROOT / "topologies" / "paper_5servers.json",
                             ROOT / "placements" / "paper_5servers.json")
    world = build_world(scenario, use_case, load_inputs(use_case), args.steps, seed=args.seed,
                        phase="test", settings=world_settings("calibrated"))
    n = world.n_servers
    policies = [NearestFree(n, np.random.default_rng(args.seed)),
                make_baseline("MinProp-1", n, np.random.default_rng(args.seed)),
                make_baseline("MinProp-2", n, np.random.default_rng(args.seed)),
                make_baseline("Oracle", n, np.random.default_rng(args.seed))]
    print(f"UC{use_case.number}, {args.steps} requests, seed {args.seed}")
    print(f"{'method':<14} {'median':>7} {'p90':>7} {'p95':>7} {'p99':>7} {'fallbacks':>9} {'copies':>6}")
    for policy in policies:
        records = simulate(world, policy)
        latency = np.array([r.latency_s for r in records])
        p50, p90, p95, p99 = np.percentile(latency, [50, 90, 95, 99])
        fallbacks = sum(r.fallback for r in records)
        copies = np.mean([r.n_selected for r in records])  # copies sent per request
        print(f"{policy.name:<14} {p50:7.3f} {p90:7.3f} {p95:7.3f} {p99:7.3f} {fallbacks:9d} {copies:6.2f}")


if __name__ == "__main__":
    main()
