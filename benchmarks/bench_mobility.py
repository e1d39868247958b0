"""What a moving user costs per request: a phase drawn and simulated at rest against on the move.

One UC1 test phase on the example campus (topologies/campus_5servers.json), drawn by
``build_world`` and run by the edge simulator with Oracle and the x = 1 baselines (no
TensorFlow: SafeTail's network costs the same per request whether the user moves or not, and
would only hide the difference). The two worlds alternate, ``--pairs`` times, and the figure
is the median over pairs of moving / at rest (issue 43's goal: at most 1.10).

    python benchmarks/bench_mobility.py [--steps 4000] [--pairs 5] [--seed 0]

About a minute on one core.
"""

from __future__ import annotations

import argparse
import statistics
import time

from yafs_safetail.defaults import DATA_ROOT
from yafs_safetail.edge.calibration import LANDED
from yafs_safetail.edge.inputs import load_inputs, load_scenario_for
from yafs_safetail.edge.mobility import RandomWaypoint
from yafs_safetail.edge.movement import MobilityPlan, default_area_m
from yafs_safetail.edge.signal import DEFAULT_SIGNAL_RULE
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world
from yafs_safetail.methods.registry import make_baseline, method_rng
from yafs_safetail.sim.runner import simulate

METHODS = ("Oracle", "Rand-1", "MinLoad-1", "MinProp-1")
WALKING_MPS = (1.0, 1.5)


def one_phase_s(mobility: MobilityPlan | None, steps: int, seed: int) -> float:
    """Seconds to draw the phase's world and run every method over it."""
    use_case = get_use_case(1)
    inputs = load_inputs(use_case)
    scenario = load_scenario_for(inputs, DATA_ROOT / "topologies" / "campus_5servers.json",
                                 DATA_ROOT / "placements" / "campus_5servers.json")
    start = time.perf_counter()
    world = build_world(scenario, use_case, inputs, steps, seed=seed, phase="test", settings=LANDED,
                        mobility=mobility)
    for name in METHODS:
        simulate(world, make_baseline(name, world.n_servers, method_rng(seed, name)))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    use_case = get_use_case(1)
    scenario = load_scenario_for(load_inputs(use_case), DATA_ROOT / "topologies" / "campus_5servers.json",
                                 DATA_ROOT / "placements" / "campus_5servers.json")
    walking = MobilityPlan(random_waypoint=RandomWaypoint(default_area_m(scenario, DEFAULT_SIGNAL_RULE),
                                                          WALKING_MPS, pause_s=30.0))
    one_phase_s(None, 200, args.seed)  # warm the caches (traces, compute model) once
    rest_s, moving_s = [], []
    for _ in range(args.pairs):
        rest_s.append(one_phase_s(None, args.steps, args.seed))
        moving_s.append(one_phase_s(walking, args.steps, args.seed))
    ratios = [m / r for m, r in zip(moving_s, rest_s, strict=True)]
    per_request = args.steps * len(METHODS)
    print(f"at rest: {1e6 * statistics.median(rest_s) / per_request:.1f} µs per request "
          f"({args.steps} requests x {len(METHODS)} methods)")
    print(f"walking: {1e6 * statistics.median(moving_s) / per_request:.1f} µs per request")
    print(f"moving / at rest: median {statistics.median(ratios):.3f} over {args.pairs} pairs "
          f"(range {min(ratios):.3f}-{max(ratios):.3f}; goal <= 1.10)")


if __name__ == "__main__":
    main()
