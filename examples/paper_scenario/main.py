"""The paper's scenario as a plain YAFS-style script.

One user, an access point and five edge servers (topologies/paper_5servers.json), the service
on every server (placements/paper_5servers.json), one request per simulated minute, and a
baseline selection. Prints the latency percentiles the paper reports.

    python examples/paper_scenario/main.py --uc 1 --method Rand-2 --steps 300
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from yafs_safetail.edge.scenario import load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, load_inputs
from yafs_safetail.methods import make_baseline
from yafs_safetail.sim.hooks import EdgeModel, edge_application
from yafs_safetail.sim.placement import EdgePlacement
from yafs_safetail.sim.population import EdgePopulation
from yafs_safetail.sim.selection import PolicySelection
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.topology import Topology

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, default=1, help="use case 1, 2 or 3")
    parser.add_argument("--method", default="Rand-2", help="Oracle, Rand-x, MinLoad-x or MinProp-x")
    parser.add_argument("--steps", type=int, default=300, help="requests (one per simulated minute)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--topology", default=str(ROOT / "topologies" / "paper_5servers.json"))
    parser.add_argument("--placement", default=str(ROOT / "placements" / "paper_5servers.json"))
    parser.add_argument("--results", default=None, help="path prefix for the YAFS CSVs (none if omitted)")
    args = parser.parse_args()

    use_case = get_use_case(args.uc)
    scenario = load_scenario(args.topology, args.placement)
    world = build_world(scenario, use_case, load_inputs(use_case), args.steps, seed=args.seed, phase="test")
    edge = EdgeModel(world)

    topology = Topology()
    topology.load(scenario.topology.data)
    sim = Sim(topology, default_results_path=args.results, link_delay=edge, service_model=edge,
              write_results=args.results is not None)
    app = edge_application(scenario.app_name, scenario.module_name)
    policy = make_baseline(args.method, edge.n_servers, np.random.default_rng(args.seed))
    selection = PolicySelection(edge, policy)
    population = EdgePopulation(scenario.user_node)
    sim.deploy_app(app, EdgePlacement(scenario.placement), population, selection)
    sim.run(until=population.until_s(args.steps))

    latency = np.array([r.latency_s for r in selection.records])
    p50, p90, p95, p99 = np.percentile(latency, [50, 90, 95, 99])
    fallbacks = sum(r.fallback for r in selection.records)
    print(f"UC{use_case.number} {use_case.name}, {selection.name}, {len(latency)} requests")
    print(f"median {p50:.3f} s  p90 {p90:.3f} s  p95 {p95:.3f} s  p99 {p99:.3f} s")
    print(f"mean target {world.target_s.mean():.3f} s, fallbacks {fallbacks}")


if __name__ == "__main__":
    main()
