"""The one simulation: every request of a pre-drawn world through the YAFS core, one policy.

The experiment, the Gymnasium environment, the examples and the tests all meet the edge world
here (a YAFS-style script can do the same by hand, see ``examples/paper_scenario/main.py``).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.methods.policy import Policy
from yafs_safetail.record import RequestRecord
from yafs_safetail.sim.hooks import EdgeModel, edge_application
from yafs_safetail.sim.placement import EdgePlacement
from yafs_safetail.sim.population import DEFAULT_STEP_INTERVAL_S, EdgePopulation
from yafs_safetail.sim.selection import PolicySelection
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.topology import Topology

#: Requests simulated between two progress-bar updates.
PROGRESS_CHUNK_STEPS = 500


class SimulationError(ValueError):
    """A simulation that could not complete every request of its world (a setting such as
    ``step_interval_s`` that does not fit the world; reported as one line)."""


@dataclass
class Simulation:
    """A deployed YAFS simulation of one world and one policy, advanced request by request.

    Attributes:
        sim: the YAFS core.
        edge: the world's delay and service hooks.
        selection: the selection driving the policy (its ``records`` fill as requests complete).
        population: the user's requests.
    """

    sim: Sim
    edge: EdgeModel
    selection: PolicySelection
    population: EdgePopulation

    def run_until_request(self, n_requests: int) -> None:
        """Run until the first ``n_requests`` requests have been emitted and completed (one
        request every ``population.step_interval_s``, each finished before the next)."""
        until_s = n_requests * self.population.step_interval_s
        if until_s > self.sim.env.now:  # simpy refuses to run up to the present
            self.sim.run(until=until_s)

    @property
    def records(self) -> list[RequestRecord]:
        return self.selection.records


def deploy(world: EdgeWorld, policy: Policy, step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
           results_path: Path | None = None) -> Simulation:
    """A fresh Sim over ``world`` (its scenario gives topology and placement) driven by ``policy``.

    Args:
        world: the phase's pre-drawn world.
        policy: the method.
        step_interval_s: time between requests.
        results_path: YAFS results path prefix (None: no YAFS CSVs).
    """
    scenario = world.scenario
    edge = EdgeModel(world)
    topology = Topology()
    topology.load(scenario.topology.data)
    sim = Sim(
        topology,
        default_results_path=str(results_path) if results_path else None,
        link_delay=edge,
        service_model=edge,
        write_results=results_path is not None,
    )
    selection = PolicySelection(edge, policy)
    population = EdgePopulation(scenario.user_node, step_interval_s)
    sim.deploy_app(
        edge_application(scenario.app_name, scenario.module_name),
        EdgePlacement(scenario.placement),
        population,
        selection,
    )
    return Simulation(sim, edge, selection, population)


def simulate(
    world: EdgeWorld,
    policy: Policy,
    step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
    results_path: Path | None = None,
    progress_label: str | None = None,
    n_requests: int | None = None,
) -> list[RequestRecord]:
    """Run every request of ``world`` (or its first ``n_requests``) with ``policy``.

    Args:
        world: the phase's pre-drawn world.
        policy: the method.
        step_interval_s: time between requests.
        results_path: YAFS results path prefix (None: no YAFS CSVs).
        progress_label: show a progress bar with this label (None: silent).
        n_requests: run only the world's first requests (None: all of them).

    Returns:
        One record per request, in step order.

    Raises:
        SimulationError: a request did not complete before the next one was due.
    """
    simulation = deploy(world, policy, step_interval_s, results_path)
    n_steps = world.n_steps if n_requests is None else min(int(n_requests), world.n_steps)
    bar = None
    if progress_label is not None:
        from tqdm import tqdm

        bar = tqdm(total=n_steps, desc=progress_label, unit="req", file=sys.stderr, leave=False)
    done = 0
    while done < n_steps:
        # Chunked runs only to move the progress bar; Sim.run continues the same simulation.
        done = min(n_steps, done + PROGRESS_CHUNK_STEPS)
        simulation.run_until_request(done)
        if bar is not None:
            bar.update(len(simulation.records) - bar.n)
    if bar is not None:
        bar.close()
    if len(simulation.records) != n_steps:
        raise SimulationError(
            f"{policy.name}: {len(simulation.records)} of {n_steps} requests completed; "
            f"step_interval_s={step_interval_s} may be shorter than a request's latency "
            "(run_usecase.py --step-interval-s)"
        )
    return simulation.records
