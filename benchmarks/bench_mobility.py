"""What a moving user costs: per request, per whole run, and the mobility sweep's time.

1. **The request path**: one UC1 test phase on the example campus
   (topologies/campus_5servers.json), drawn by ``build_world`` and run by the edge simulator
   with Oracle and the x = 1 baselines (no TensorFlow, which costs the same per request either
   way and would only hide the difference), at rest and walking, alternating ``--pairs`` times.
2. **A whole run**: ``run_usecase.py --uc 1`` on the campus, at rest against ``--mobility
   random-waypoint``, each its own process, alternating ``--run-pairs`` times.
3. **The sweep**: ``mobility_sweep.py --seeds 0,1,2`` (three speeds, nine full UC1 runs) once,
   its wall time (skip with ``--run-pairs 0``).

Each ratio is the median over pairs of moving / at rest (issue 43's goal: at most 1.10).

    python benchmarks/bench_mobility.py [--steps 4000] [--pairs 5] [--run-pairs 3] [--seed 0]

About three minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from yafs_safetail.defaults import DATA_ROOT
from yafs_safetail.edge.calibration import LANDED
from yafs_safetail.edge.inputs import load_inputs, load_scenario_for
from yafs_safetail.edge.movement import MobilityPlan, default_area_m
from yafs_safetail.edge.routes import RandomWaypoint
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


ROOT = Path(__file__).resolve().parents[1]
CAMPUS_RUN = ["--uc", "1", "--topology", "topologies/campus_5servers.json", "--no-figures", "--quiet"]


def timed_s(arguments: list[str]) -> float:
    """Wall seconds of one command in its own process (it must succeed)."""
    start = time.perf_counter()
    subprocess.run([sys.executable, *arguments], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def whole_runs(pairs: int, seed: int) -> None:
    with tempfile.TemporaryDirectory() as scratch:
        script = str(ROOT / "experiments" / "run_usecase.py")
        rest_s, moving_s = [], []
        for pair in range(pairs):
            common = [script, *CAMPUS_RUN, "--seed", str(seed)]
            rest_s.append(timed_s([*common, "--out", f"{scratch}/rest{pair}"]))
            moving_s.append(timed_s([*common, "--mobility", "random-waypoint", "--out", f"{scratch}/moving{pair}"]))
        ratios = [m / r for m, r in zip(moving_s, rest_s, strict=True)]
        print(f"whole UC1 run: at rest {statistics.median(rest_s):.1f} s, walking {statistics.median(moving_s):.1f} s; "
              f"moving / at rest: median {statistics.median(ratios):.3f} over {pairs} pairs "
              f"(range {min(ratios):.3f}-{max(ratios):.3f}; goal <= 1.10)")
        sweep_s = timed_s([str(ROOT / "experiments" / "mobility_sweep.py"), "--seeds", "0,1,2", "--no-figures",
                           "--quiet", "--out", f"{scratch}/sweep"])
        print(f"mobility sweep (UC1, rest/walking/driving x seeds 0,1,2, full budget): {sweep_s:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--run-pairs", type=int, default=3)
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
    if args.run_pairs:
        whole_runs(args.run_pairs, args.seed)


if __name__ == "__main__":
    main()
