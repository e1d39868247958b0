"""The paper's scenario as a plain YAFS-style script.

One user, an access point and five edge servers (topologies/paper_5servers.json), the service
on every server (placements/paper_5servers.json), one request per simulated minute, and a
baseline selection. Prints the latency percentiles the paper reports.

    python examples/paper_scenario/main.py --uc 1 --method Rand-2 --steps 300

The world (each request's input, the links' and servers' conditions, the background load, the
target latency) is drawn by the world recipe a run uses for its test phase, and the method gets
the generator a run gives it: a run's test phase has ``--steps-scale`` × 20·β requests (UC1:
β = 200, so ``--steps 300`` is ``--steps-scale 0.075``), and for the same method, seed and
requests this prints the figures that run's summary.csv has for the method.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from yafs_safetail.defaults import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.methods.registry import make_baseline, method_rng
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.sim.hooks import EdgeModel, edge_application
from yafs_safetail.sim.placement import EdgePlacement
from yafs_safetail.sim.population import EdgePopulation
from yafs_safetail.sim.selection import PolicySelection
from yafs_safetail.worlds.recipe import TEST, world_recipe
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.topology import Topology


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, default=1, help="use case 1, 2 or 3")
    parser.add_argument("--method", default="Rand-2", help="Oracle, Rand-x, MinLoad-x or MinProp-x")
    parser.add_argument("--steps", type=int, default=300, help="requests (one per simulated minute)")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed (default 0, as a run's)")
    parser.add_argument("--topology", default=str(DEFAULT_TOPOLOGY))
    parser.add_argument("--placement", default=str(DEFAULT_PLACEMENT))
    parser.add_argument("--results", default=None, help="path prefix for the YAFS CSVs (none if omitted)")
    args = parser.parse_args(argv)

    # The paper's world, drawn as a run draws its test world (the preset's world settings, the
    # traces and compute model, the topology checked against them), with --steps requests.
    config = ExperimentConfig(use_case=args.uc, seed=args.seed,
                              topology=Path(args.topology), placement=Path(args.placement))
    recipe = dataclasses.replace(world_recipe(config), test_steps=args.steps)
    world = recipe.make_world(TEST, args.seed)
    scenario = world.scenario
    edge = EdgeModel(world)  # the world's link delays and service times, as YAFS hooks

    # YAFS: the topology, the simulator, the application, its placement, the user, the selection.
    topology = Topology()
    topology.load(scenario.topology.data)
    sim = Sim(topology, default_results_path=args.results, link_delay=edge, service_model=edge,
              write_results=args.results is not None)
    app = edge_application(scenario.app_name, scenario.module_name)
    policy = make_baseline(args.method, edge.n_servers, method_rng(args.seed, args.method),
                           world.settings.baseline_reading)
    selection = PolicySelection(edge, policy)
    population = EdgePopulation(scenario.user_node, recipe.step_interval_s)
    sim.deploy_app(app, EdgePlacement(scenario.placement), population, selection)
    sim.run(until=population.until_s(args.steps))

    latency = np.array([r.latency_s for r in selection.records])
    p50, p90, p95, p99 = np.percentile(latency, [50, 90, 95, 99])
    fallbacks = sum(r.fallback for r in selection.records)
    use_case = recipe.use_case
    print(f"UC{use_case.number} {use_case.name}, {selection.name}, {len(latency)} requests")
    print(f"median {p50:.3f} s  p90 {p90:.3f} s  p95 {p95:.3f} s  p99 {p99:.3f} s")
    print(f"mean target {world.target_s.mean():.3f} s, fallbacks {fallbacks}")


if __name__ == "__main__":
    main()
