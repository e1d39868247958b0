"""EdgePopulation: the user issuing one request per step, and the sink that keeps its replies."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

# In defaults.py, since the command line shows it before anything loads.
from yafs_safetail.defaults import DEFAULT_STEP_INTERVAL_S as DEFAULT_STEP_INTERVAL_S
from yafs_safetail.sim.hooks import REQUEST_MESSAGE, SINK_MODULE
from yafs_safetail.yafs.distribution import Distribution, deterministicDistributionStartPoint
from yafs_safetail.yafs.population import Population

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim



class EdgePopulation(Population):
    """A YAFS :class:`Population`: the user's source and sink on the user node.

    By default the user emits one request every ``step_interval_s`` starting at time 0, so
    step *t*'s request leaves at ``t * step_interval_s`` and ``Sim.run(until=n *
    step_interval_s)`` runs exactly *n* requests (every copy finishes well within a minute).
    Any YAFS distribution can replace the default.

    Args:
        user_node: the user's node id (``EdgeScenario.user_node``).
        step_interval_s: time between requests for the default distribution.
        distribution: a YAFS distribution of inter-arrival times (overrides the default).
        name: the population's name.
        first_step: the world step of the first request: a simulation resumed from a training
            checkpoint starts its clock where the uninterrupted one emitted that request.
    """

    def __init__(
        self,
        user_node: Any,
        step_interval_s: float = DEFAULT_STEP_INTERVAL_S,
        distribution: Distribution | None = None,
        name: str = "EdgePopulation",
        first_step: int = 0,
    ) -> None:
        super().__init__(name)
        if not step_interval_s > 0:
            raise ValueError(f"step_interval_s: must be positive, got {step_interval_s!r}")
        self.user_node = user_node
        self.step_interval_s = float(step_interval_s)
        self.first_step = int(first_step)
        self.distribution = distribution
        self.source_des: int | None = None
        self.sink_des: int | None = None

    def until_s(self, n_requests: int) -> float:
        """The ``Sim.run(until=...)`` that runs this population's first ``n_requests``
        requests with the default one-per-step arrivals."""
        return (self.first_step + n_requests) * self.step_interval_s

    def _first_emission_s(self) -> float:
        # The time an uninterrupted simulation emits step first_step's request: the same sum
        # of intervals simpy accumulates, so a resumed run sees the very same clock readings.
        time_s = 0.0
        for _ in range(self.first_step):
            time_s += self.step_interval_s
        return time_s

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        app = sim.apps[app_name]
        self.sink_des = sim.deploy_sink(app_name, node=self.user_node, module=SINK_MODULE)
        self.source_des = sim.deploy_source(
            app_name, id_node=self.user_node, msg=app.get_message(REQUEST_MESSAGE),
            distribution=self.distribution or deterministicDistributionStartPoint(
                self._first_emission_s(), self.step_interval_s, name="EdgeStep"
            ),
        )
