"""Plug in your own policy: a SubsetSelection subclass compared with SafeTail's baselines.

``NearestFreeX`` sends each request to the x servers with the lowest median propagation
among those that still have room (fewer than the load limit of active users), falling back
to the nearest ones when all are full. It sees exactly what SafeTail sees (the Observation,
ω^t) and runs on exactly the same requests as the baselines (common random numbers).

    python examples/custom_policy/main.py --uc 1 --steps 400
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from yafs_safetail.edge.model import EdgeModel
from yafs_safetail.edge.observation import Observation
from yafs_safetail.edge.topology_io import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import DEFAULT_MAX_LOAD, build_world, load_inputs
from yafs_safetail.experiment import simulate
from yafs_safetail.selection import SubsetSelection, make_baseline

ROOT = Path(__file__).resolve().parents[2]


class NearestFreeX(SubsetSelection):
    """The x nearest servers (by median propagation) that are below the load limit."""

    def __init__(self, edge_model: EdgeModel, x: int, **kwargs) -> None:
        self.x = x
        super().__init__(edge_model, **kwargs)

    def default_name(self) -> str:
        return f"NearestFree-{self.x}"

    def choose_subset(self, step: int, observation: Observation) -> tuple[int, ...]:
        full = observation.server_active_users >= DEFAULT_MAX_LOAD
        # Full servers sort after every free one; among each group, nearest first.
        order = np.lexsort((observation.server_median_propagation_s, full))
        return tuple(order[: self.x].tolist())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, default=1)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    use_case = get_use_case(args.uc)
    scenario = load_scenario(ROOT / "topologies" / "paper_5servers.json",
                             ROOT / "placements" / "paper_5servers.json")
    world = build_world(scenario, use_case, load_inputs(use_case), args.steps, seed=args.seed, phase="test")
    methods = {
        "NearestFree-1": lambda edge: NearestFreeX(edge, 1),
        "MinProp-1": lambda edge: make_baseline("MinProp-1", edge, np.random.default_rng(args.seed)),
        "Oracle": lambda edge: make_baseline("Oracle", edge, np.random.default_rng(args.seed)),
    }
    print(f"UC{use_case.number}, {args.steps} requests, seed {args.seed}")
    print(f"{'method':<14} {'median':>7} {'p90':>7} {'p95':>7} {'p99':>7} {'fallbacks':>9}")
    for name, factory in methods.items():
        records = simulate(world, factory)
        latency = np.array([r.latency_s for r in records])
        p50, p90, p95, p99 = np.percentile(latency, [50, 90, 95, 99])
        fallbacks = sum(r.fallback for r in records)
        print(f"{name:<14} {p50:7.3f} {p90:7.3f} {p95:7.3f} {p99:7.3f} {fallbacks:9d}")


if __name__ == "__main__":
    main()
