"""Can any world of the calibration grid give the target the headroom the paper's numbers imply?

A learner-free measurement (no TensorFlow). The paper says SafeTail is below the target τ at some
percentiles while being a stated factor slower than Oracle there; together these imply a lower
bound on τ over Oracle's latency that holds for *any* policy meeting them:

    UC1: SafeTail below τ at every percentile, Oracle 1.08x faster at p50 -> τ/Oracle p50 >= 1.08
    UC3: SafeTail below τ at p50 and p90, Oracle 1.50x / 1.14x faster -> τ/Oracle >= 1.50 / 1.14

For each use case and each (bandwidth-share exponent γ, load peak) at the grid's corners and
at the fitted point, this prints the mean τ over Oracle's p50 and p90 on the world-calibration
seeds' test worlds, and the share of Oracle's median latency that is compute. If no row of a
use case reaches its bound, no fit of these two parameters can make that use case's statements
hold together, whatever the learner does.

    python investigations/bench_target_headroom.py [--seeds 1000,1001,1002] [--steps 2000]

About a minute on 2 cores.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from yafs_safetail.edge.calibration import calibrated_settings, read_calibration, seed_set
from yafs_safetail.edge.inputs import load_inputs, load_scenario_for
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS, EdgeWorld, build_world
from yafs_safetail.methods.registry import ORACLE, SAFETAIL
from yafs_safetail.results.paper import paper_speedup
from yafs_safetail.runs.calibrate import GRID

#: Percentiles at which the paper puts SafeTail below τ (facts.md's table), per use case.
BELOW_TARGET_AT = {1: (50, 90, 95, 99), 2: (50,), 3: (50, 90)}


def implied_bound(use_case: int, percentile: int) -> float:
    """τ over Oracle's latency at ``percentile`` that the paper's statements imply (>=)."""
    oracle_speedup = paper_speedup(use_case, ORACLE, SAFETAIL, percentile)
    # UC2 publishes no SafeTail-vs-Oracle ratio: "below τ" alone bounds τ by Oracle's latency.
    return 1.0 if oracle_speedup is None else oracle_speedup


def headroom(use_case_number: int, gamma: float, load_peak: float, seeds: list[int],
             n_steps: int) -> tuple[float, float, float]:
    """Mean over seeds of τ/Oracle p50, τ/Oracle p90, and compute's share of Oracle's median."""
    use_case = get_use_case(use_case_number)
    inputs = load_inputs(use_case)
    scenario = load_scenario_for(inputs, DEFAULT_TOPOLOGY, DEFAULT_PLACEMENT)
    shipped = read_calibration()
    parameters = dict(shipped["parameters"], bandwidth_share_exponent=gamma,
                      load_peak_users=load_peak)
    settings = calibrated_settings(parameters, shipped["readings"])
    rows = [target_over_oracle(build_world(scenario, use_case, inputs, n_steps, seed=seed, phase="test",
                                           episode_steps=DEFAULT_EPISODE_STEPS, settings=settings))
            for seed in seeds]
    return tuple(float(v) for v in np.mean(rows, axis=0))  # type: ignore[return-value]


def target_over_oracle(world: EdgeWorld) -> tuple[float, float, float]:
    """One world's mean τ over Oracle's p50 and p90, and compute's share of Oracle's median."""
    table = world.copy_latency_table_s()
    best = np.argmin(np.where(np.isfinite(table), table, np.inf), axis=1)
    oracle_s = table[np.arange(world.n_steps), best]
    served = np.isfinite(oracle_s)
    compute_s = world.compute_by_processes_s[np.arange(world.n_steps), best,
                                             np.minimum(world.background_users[
                                                 np.arange(world.n_steps), best],
                                                 world.max_load - 1)]
    mean_target_s = float(np.mean(world.target_s))
    p50, p90 = np.percentile(oracle_s[served], (50, 90))
    return mean_target_s / p50, mean_target_s / p90, float(np.median(compute_s[served]) / p50)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default=None,
                        help="comma-separated seeds (default: the first three world-calibration seeds)")
    parser.add_argument("--steps", type=int, default=2000, help="test requests per world")
    args = parser.parse_args(argv)
    seeds = ([int(s) for s in args.seeds.split(",")] if args.seeds
             else seed_set("world_calibration")[:3])
    fitted = read_calibration()["parameters"]
    gammas = sorted({GRID["bandwidth_share_exponent"][0], float(fitted["bandwidth_share_exponent"]),
                     GRID["bandwidth_share_exponent"][-1]})
    peaks = sorted({GRID["load_peak_users"][0], float(fitted["load_peak_users"]),
                    GRID["load_peak_users"][-1]})
    print(f"seeds={','.join(map(str, seeds))} steps={args.steps}")
    print("uc gamma load_peak tau/oracle_p50 tau/oracle_p90 compute_share_of_oracle_p50")
    for use_case in (1, 2, 3):
        best_p50 = best_p90 = 0.0
        for gamma in gammas:
            for peak in peaks:
                p50, p90, share = headroom(use_case, gamma, peak, seeds, args.steps)
                best_p50, best_p90 = max(best_p50, p50), max(best_p90, p90)
                print(f"{use_case} {gamma:g} {peak:g} {p50:.3f} {p90:.3f} {share:.2f}")
        bounds = {p: implied_bound(use_case, p) for p in BELOW_TARGET_AT[use_case] if p in (50, 90)}
        reached = all((best_p50 if p == 50 else best_p90) >= bound for p, bound in bounds.items())
        bound_text = " ".join(f"p{p}>={b:.2f}" for p, b in bounds.items())
        print(f"uc{use_case}_implied {bound_text} best_p50={best_p50:.3f} best_p90={best_p90:.3f} "
              f"reachable={'yes' if reached else 'no'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
