"""Placement policies: where module replicas run (YAFS's ``yafs.placement``)."""

from __future__ import annotations

import logging
import os
from typing import TYPE_CHECKING, Any

from yafs_safetail.yafs.distribution import Distribution
from yafs_safetail.yafs.errors import (
    YAFSInputError,
    read_json_input,
    require_id,
    require_list,
    require_mapping,
)

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim

logger = logging.getLogger(__name__)


class Placement:
    """Base class: ``initial_allocation`` at start, ``run`` every ``activation_dist.next()``.

    Inside either hook, call ``sim.deploy_module(app_name, module, services, [node_ids])``.

    Args:
        name: the placement's name (one control process per name).
        activation_dist: when to call :meth:`run`; ``None`` = never.
        logger: the placement's logger (YAFS's ``self.logger``; default: this module's).
    """

    def __init__(self, name: str, activation_dist: Distribution | None = None,
                 logger: logging.Logger | None = None) -> None:
        self.logger = logger or logging.getLogger(__name__)
        self.name = name
        self.activation_dist = activation_dist
        self.scaleServices: dict[str, int] = {}

    def scaleService(self, scale: dict[str, int]) -> None:  # noqa: N802 - YAFS name
        """Set the number of replicas per module (used by placements such as CloudPlacement)."""
        self.scaleServices = scale

    def get_next_activation(self) -> float:
        """Time until the next :meth:`run`."""
        assert self.activation_dist is not None
        return self.activation_dist.next()

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        """Deploy the initial replicas of ``app_name``'s modules (override)."""

    def run(self, sim: Sim) -> None:
        """Change the deployment during the simulation (override)."""
        self.logger.debug("Activating - RUN - Placement")


class JSONPlacement(Placement):
    """Replicas read from a placement JSON: ``{"initialAllocation": [{module_name, app, id_resource}]}``.

    Args:
        json: the parsed JSON or a path to the file.
        name: the placement's name.
        activation_dist: as in :class:`Placement`.

    Raises:
        YAFSInputError: at construction for a malformed document; at allocation for an
            entry naming a node or module that does not exist.
    """

    def __init__(
        self,
        json: dict[str, Any] | str | os.PathLike[str],
        name: str = "JSONPlacement",
        activation_dist: Distribution | None = None,
        logger: logging.Logger | None = None,
    ) -> None:
        super().__init__(name, activation_dist, logger)
        data, self.source = read_json_input(json, "placement")
        root = require_mapping(data, self.source, "")
        self.data = root
        self._entries: list[tuple[str, str, Any, Any]] = []
        for index, raw in enumerate(require_list(root, "initialAllocation", self.source, "")):
            entry = f"initialAllocation[{index}]"
            item = require_mapping(raw, self.source, entry)
            module = require_id(item, "module_name", self.source, entry)
            app = require_id(item, "app", self.source, entry)
            node = require_id(item, "id_resource", self.source, entry)
            self._entries.append((entry, module, app, node))

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        for entry, module, app, node in self._entries:
            if app != app_name:
                continue
            services = sim.apps[app_name].services
            if module not in services:
                raise YAFSInputError(
                    self.source, entry, "module_name",
                    f"app {app_name!r} has no module {module!r} with a service",
                )
            target = self._node_for(entry, node, sim)
            sim.deploy_module(app_name, module, services[module], [target])

    def _node_for(self, entry: str, node: Any, sim: Sim) -> Any:
        """The node an entry's replica goes to: its ``id_resource``, which must exist."""
        if node not in sim.topology.G:
            raise YAFSInputError(
                self.source, entry, "id_resource", f"node {node!r} is not in the topology"
            )
        return node

    def validate_apps(self, apps: dict[Any, Any]) -> None:
        """Raise if an entry names an application that is not in ``apps``."""
        for entry, _module, app, _node in self._entries:
            if app not in apps:
                raise YAFSInputError(self.source, entry, "app", f"names unknown application {app!r}")


class JSONPlacementOnCloud(JSONPlacement):
    """Every module named in a placement JSON is deployed on one node, ``idCloud`` (YAFS3):
    the entries' ``id_resource`` is ignored.

    Args:
        json: the parsed JSON or a path to the file.
        idCloud: the node that receives every replica.
        name: the placement's name.
        activation_dist: as in :class:`Placement`.
    """

    def __init__(self, json: dict[str, Any] | str | os.PathLike[str], idCloud: Any,  # noqa: N803
                 name: str = "JSONPlacementOnCloud", activation_dist: Distribution | None = None,
                 logger: logging.Logger | None = None) -> None:
        super().__init__(json, name, activation_dist, logger)
        self.idCloud = idCloud

    def _node_for(self, entry: str, node: Any, sim: Sim) -> Any:
        return self.idCloud  # YAFS3 does not check the cloud node either


class ClusterPlacement(Placement):
    """YAFS3's example placement: ``scaleServices`` replicas of ``Coordinator`` and of
    ``Calculator`` on the nodes whose ``model`` is ``"Cluster"``, and ``Client`` on every
    node whose ``model`` is ``"m-"`` (other modules are not placed)."""

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        cluster = sim.topology.find_IDs({"model": "Cluster"})
        mobiles = sim.topology.find_IDs({"model": "m-"})
        services = sim.apps[app_name].services
        for module in services:
            if module in ("Coordinator", "Calculator"):
                for _ in range(self.scaleServices.get(module, 0)):
                    sim.deploy_module(app_name, module, services[module], cluster)
            elif module == "Client":
                sim.deploy_module(app_name, module, services[module], mobiles)


class EdgePlacement(Placement):
    """YAFS3's example placement: ``Coordinator`` on the ``"Cluster"`` nodes,
    ``Calculator`` on the ``"d-"`` nodes, ``Client`` on the ``"m-"`` nodes (one replica per
    node; YAFS3 also prints each module name, which this does not)."""

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        where = {"Coordinator": sim.topology.find_IDs({"model": "Cluster"}),
                 "Calculator": sim.topology.find_IDs({"model": "d-"}),
                 "Client": sim.topology.find_IDs({"model": "m-"})}
        services = sim.apps[app_name].services
        for module in services:
            if module in where:
                sim.deploy_module(app_name, module, services[module], where[module])


class NoPlacementOfModules(Placement):
    """Places nothing: for applications made only of pure sources and sinks (YAFS3)."""

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        return None
