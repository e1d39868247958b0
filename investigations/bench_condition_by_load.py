"""Would the original code's propagation reading help the world fit? Learner-free, calibration seeds.

facts.md ("What the original code did") says MinProp-x keyed on the propagation value the state
showed, which "informed the choice only through its load level": the original drew each server's
propagation from the pool of its load level, so a busy server was also a far one. Our world
keeps each link's condition (1..5) fixed in the topology. This prints rule 1's objective
(docs/calibration.md: UC1's twelve x = 1 cells over Oracle's, mean |log(ours / implied)|) over
the grid's per-server-start candidates under two readings of a link's condition:

* ``topology``: the condition the topology gives (today's world);
* ``load-level``: at each step, the server's background users + 1 (0..4 users -> conditions
  1..5), the RTT drawn at the same quantile from that condition's pool, and MinProp-1 (the
  original code's reading) keyed on that step's median propagation.

Nothing here changes a run; it answers whether the reading is worth a rule.

    python investigations/bench_condition_by_load.py [--seeds 1000,1001,1002] [--top 3]

About two minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from yafs_safetail.edge import sampling
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS, EdgeWorld, build_world, phase_streams
from yafs_safetail.methods.registry import ORACLE
from yafs_safetail.results.files import PERCENTILES
from yafs_safetail.runs import calibrate, world_fit

CONDITIONS = (1, 2, 3, 4, 5)


def condition_by_load(world: EdgeWorld, inputs: object, seed: int) -> tuple[EdgeWorld, np.ndarray]:
    """``world`` with each (step, server) RTT drawn from the pool of its load level's condition,
    at the same quantile the world drew; and the median propagation per (step, server)."""
    servers = sampling.draw_servers(phase_streams(seed, "test")["servers"], world.n_servers, world.n_steps)
    condition = np.clip(world.background_users + 1, 1, 5)
    fraction = world.settings.propagation_rtt_fraction
    extra_s = world.median_propagation_s - np.array(
        [np.median(inputs.rtt_pools_s[c] * fraction) for c in world.scenario.server_conditions])  # type: ignore[attr-defined]
    rtt_s = np.empty(condition.shape)
    median_s = np.empty(condition.shape)
    for c in CONDITIONS:
        pool = inputs.rtt_pools_s[c] * fraction  # type: ignore[attr-defined]
        here = condition == c
        rtt_s[here] = sampling.quantile_lookup(pool, servers.rtt_quantiles[here])
        median_s[here] = float(np.median(pool))
    return dataclasses.replace(world, rtt_s=rtt_s + extra_s[None, :]), median_s + extra_s[None, :]


def latencies_by_load(world: EdgeWorld, median_s: np.ndarray,
                      choices: world_fit.SeedChoices) -> dict[str, np.ndarray]:
    """Oracle's and the x = 1 baselines' latency, MinProp-1 keyed on each step's median."""
    latencies = world_fit.method_latencies_s(world, choices)
    steps = np.arange(world.n_steps)
    drawn = choices.minprop_candidates
    chosen = drawn[steps, np.argmin(median_s[steps[:, None], drawn], axis=1)]
    table = world.copy_latency_table_s()[steps, chosen]
    latencies["MinProp-1"] = np.where(np.isfinite(table), table, world.fallback_latency_s)
    return latencies


def objective(candidate: dict, seeds: list[int], reading: str) -> tuple[float, dict[str, float]]:
    use_case, inputs, scenario = world_fit._scenario(str(world_fit.DEFAULT_TOPOLOGY),
                                                     str(world_fit.DEFAULT_PLACEMENT))
    settings = dataclasses.replace(world_fit.settings_for(candidate), baseline_reading="original-code")
    per_seed = []
    for seed in seeds:
        world = build_world(scenario, use_case, inputs, world_fit.TEST_STEPS, seed=seed, phase="test",
                            episode_steps=DEFAULT_EPISODE_STEPS, settings=settings)
        choices = world_fit._choices(seed, world.n_servers, world_fit.TEST_STEPS)
        if reading == "topology":
            latencies = world_fit.method_latencies_s(world, choices)
        else:
            world, median_s = condition_by_load(world, inputs, seed)
            latencies = latencies_by_load(world, median_s, choices)
        oracle = np.percentile(latencies[ORACLE], PERCENTILES)
        per_seed.append({world_fit.cell_key(m, p): float(q / o) for m in world_fit.X1_BASELINES
                         for p, q, o in zip(PERCENTILES, np.percentile(latencies[m], PERCENTILES),
                                            oracle, strict=True)})
    value, _, means = world_fit.objective(per_seed)
    return value, means


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1000,1001,1002")
    parser.add_argument("--top", type=int, default=3)
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    candidates = [c for c in calibrate.grid_candidates() if c["load_start"] == "per_server"]
    implied = world_fit.implied_over_oracle()
    print("implied  " + " ".join(f"{m[:-2]:>7}p{p}={v:.2f}" for (m, p), v in implied.items()))
    for reading in ("topology", "load-level"):
        scored = sorted(((objective(c, seeds, reading), c) for c in candidates), key=lambda s: s[0][0])
        for (value, means), candidate in scored[: args.top]:
            cells = " ".join(f"{k.split('/')[0][:-2]:>7}{k.split('/')[-1]}={v:.2f}" for k, v in means.items())
            print(f"{reading:<10} peak {candidate['load_peak_users']:.2f} γ {candidate['bandwidth_share_exponent']:.2f}"
                  f" fallback ×{candidate['fallback_compute_multiple']:.0f} objective {value:.3f}\n           {cells}")


if __name__ == "__main__":
    main()
