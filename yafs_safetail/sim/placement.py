"""EdgePlacement: the edge service on every edge server the placement JSON names."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from yafs_safetail.edge.scenario import EdgePlacementSpec, load_placement
from yafs_safetail.edge.topology_io import JsonSource, ScenarioError
from yafs_safetail.yafs.placement import Placement

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim


class EdgePlacement(Placement):
    """A YAFS :class:`Placement` deploying one replica of the service per edge server.

    Replicas are deployed in the placement file's order, which is the server index order of
    the edge model (so replica process ids increase with the server index).

    Args:
        placement: a placement JSON path, its parsed dict, or an already validated
            :class:`EdgePlacementSpec` (e.g. ``EdgeScenario.placement``).
        name: the placement's name.

    Raises:
        ScenarioError: a malformed placement file (at construction), or an app without the
            placed module / a placed node missing from the topology (at allocation).
    """

    def __init__(self, placement: JsonSource | EdgePlacementSpec, name: str = "EdgePlacement") -> None:
        super().__init__(name)
        self.spec = placement if isinstance(placement, EdgePlacementSpec) else load_placement(placement)

    @property
    def server_nodes(self) -> tuple[Any, ...]:
        return self.spec.server_nodes

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        if app_name != self.spec.app_name:
            return
        services = sim.apps[app_name].services
        module = self.spec.module_name
        if module not in services:
            raise ScenarioError(
                self.spec.source, "initialAllocation.module_name",
                f"app {app_name!r} has no module {module!r}",
            )
        for index, node in enumerate(self.spec.server_nodes):
            if node not in sim.topology.G:
                raise ScenarioError(
                    self.spec.source, f"initialAllocation[{index}].id_resource",
                    f"node {node!r} is not in the simulated topology",
                )
            sim.deploy_module(app_name, module, services[module], [node])
