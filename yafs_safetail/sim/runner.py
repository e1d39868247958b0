"""The one simulation: every request of a pre-drawn world through the YAFS core, one policy.

The experiment, the Gymnasium environment, the examples and the tests all meet the edge world
here (a YAFS-style script can do the same by hand, see ``examples/paper_scenario/main.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.logs import Phase
from yafs_safetail.methods.policy import Policy
from yafs_safetail.record import RequestRecord
from yafs_safetail.sim.hooks import EdgeModel, edge_application
from yafs_safetail.sim.placement import EdgePlacement
from yafs_safetail.sim.population import DEFAULT_STEP_INTERVAL_S, EdgePopulation
from yafs_safetail.sim.selection import PolicySelection
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.topology import Topology

#: Requests simulated at most between two progress updates.
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

    first_step: int = 0

    def run_until_request(self, n_requests: int) -> None:
        """Run until the first ``n_requests`` requests of this simulation have been emitted and
        completed (one request every ``population.step_interval_s``, each finished before the
        next)."""
        until_s = self.population.until_s(n_requests)
        if until_s > self.sim.env.now:  # simpy refuses to run up to the present
            self.sim.run(until=until_s)

    @property
    def next_step(self) -> int:
        """The world step of the next request (every earlier one has its record)."""
        return self.first_step + len(self.records)

    @property
    def quiescent(self) -> bool:
        """No request pending and no copy running: a fresh simulation started at
        :attr:`next_step` would continue this one exactly (what a checkpoint needs)."""
        return (self.edge.requests_seen == self.next_step and not self.edge.copies_running
                and not self.selection.pending_requests)

    @property
    def records(self) -> list[RequestRecord]:
        return self.selection.records


def deploy(world: EdgeWorld, policy: Policy, step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
           results_path: Path | None = None, first_step: int = 0) -> Simulation:
    """A fresh Sim over ``world`` (its scenario gives topology and placement) driven by ``policy``.

    Args:
        world: the phase's pre-drawn world.
        policy: the method.
        step_interval_s: time between requests.
        results_path: YAFS results path prefix (None: no YAFS CSVs).
        first_step: the world step of the first request (a training phase resumed from a
            checkpoint); its records carry the steps and request ids of an uninterrupted run.
    """
    scenario = world.scenario
    edge = EdgeModel(world)
    edge.requests_seen = first_step
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
    # The core numbers requests 1, 2, ... from its start; an uninterrupted run's request of
    # step t has id t + 1.
    selection.request_id_offset = first_step
    population = EdgePopulation(scenario.user_node, step_interval_s, first_step=first_step)
    sim.deploy_app(
        edge_application(scenario.app_name, scenario.module_name),
        EdgePlacement(scenario.placement),
        population,
        selection,
    )
    return Simulation(sim, edge, selection, population, first_step)


def simulate(
    world: EdgeWorld,
    policy: Policy,
    step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
    results_path: Path | None = None,
    progress: Phase | None = None,
    n_requests: int | None = None,
    first_step: int = 0,
    after_chunk: Callable[[Simulation], None] | None = None,
    chunk_steps: int = PROGRESS_CHUNK_STEPS,
) -> list[RequestRecord]:
    """Run every request of ``world`` (or its first ``n_requests``) with ``policy``.

    Args:
        world: the phase's pre-drawn world.
        policy: the method.
        step_interval_s: time between requests.
        results_path: YAFS results path prefix (None: no YAFS CSVs).
        progress: the phase this simulation's requests count towards (its 10% lines and bar;
            several simulations may share one phase, each adding its requests; None: silent).
        n_requests: run only the world's first requests (None: all of them).
        first_step: start at this step (resuming; the records are of the later steps only).
        after_chunk: called with the simulation after every ``chunk_steps`` requests (where
            a training run writes its checkpoints).
        chunk_steps: requests between two progress updates and ``after_chunk`` calls.

    Returns:
        One record per request from ``first_step`` on, in step order.

    Raises:
        SimulationError: a request did not complete before the next one was due.
    """
    simulation = deploy(world, policy, step_interval_s, results_path, first_step)
    n_steps = (world.n_steps if n_requests is None else min(int(n_requests), world.n_steps)) - first_step
    before = 0 if progress is None else progress.done  # the phase's requests counted already
    done = 0
    while done < n_steps:
        # Chunked runs only to report progress (pausing exactly where the phase's next 10% line
        # is due) and to let a training run checkpoint; Sim.run continues the same simulation,
        # so the records do not depend on it.
        stop = done + chunk_steps
        if progress is not None:
            stop = min(stop, progress.next_line_at(before + done) - before)
        done = min(n_steps, max(stop, done + 1))
        simulation.run_until_request(done)
        if progress is not None:
            progress.update(before + len(simulation.records))
        if after_chunk is not None:
            after_chunk(simulation)
    if len(simulation.records) != n_steps:
        raise SimulationError(
            f"{policy.name}: {len(simulation.records)} of {n_steps} requests completed; "
            f"step_interval_s={step_interval_s} may be shorter than a request's latency "
            "(run_usecase.py --step-interval-s)"
        )
    return simulation.records
