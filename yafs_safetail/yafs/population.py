"""Population policies: where users (pure sources) and sinks are (YAFS's ``yafs.population``)."""

from __future__ import annotations

import logging
import os
from typing import TYPE_CHECKING, Any

from yafs_safetail.yafs.distribution import Distribution, exponential_distribution
from yafs_safetail.yafs.errors import (
    YAFSInputError,
    read_json_input,
    require_id,
    require_list,
    require_mapping,
    require_number,
)

if TYPE_CHECKING:
    from yafs_safetail.yafs.core import Sim


class Population:
    """Base class: ``initial_allocation`` at start, ``run`` every ``activation_dist.next()``.

    Inside either hook, call ``sim.deploy_source(app_name, id_node, msg, distribution)`` and
    ``sim.deploy_sink(app_name, node, module)``.

    Args:
        name: the population's name (one control process per name).
        activation_dist: when to call :meth:`run`; ``None`` = never.
        logger: the population's logger (YAFS's ``self.logger``; default: this module's).
    """

    def __init__(self, name: str, activation_dist: Distribution | None = None,
                 logger: logging.Logger | None = None) -> None:
        self.logger = logger or logging.getLogger(__name__)
        self.name = name
        self.activation_dist = activation_dist
        self.src_control: list[dict[str, Any]] = []
        self.sink_control: list[dict[str, Any]] = []

    def set_sink_control(self, values: dict[str, Any]) -> None:
        """Add a sink rule (for :class:`Statical`: ``model``, ``number``, ``module``)."""
        self.sink_control.append(values)

    def set_src_control(self, values: dict[str, Any]) -> None:
        """Add a source rule (for :class:`Statical`: ``model``, ``number``, ``message``,
        ``distribution``)."""
        self.src_control.append(values)

    def get_next_activation(self) -> float:
        """Time until the next :meth:`run`."""
        assert self.activation_dist is not None
        return self.activation_dist.next()

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        """Deploy the initial sources and sinks of ``app_name`` (override)."""

    def run(self, sim: Sim) -> None:
        """Change the population during the simulation (override)."""
        self.logger.debug("Activating - RUN - Population")


class Statical(Population):
    """Sinks and sources on every entity whose ``model`` attribute matches a rule.

    As YAFS3: entities are read from ``sim.topology.nodeAttributes`` (the entities of
    :meth:`Topology.load`, in file order; a topology given as a bare graph has none), and
    on each entity its sinks are deployed before its sources, which fixes the process ids.
    A rule's ``module`` may also be a list of sink modules (YAFS3 takes one name).
    """

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        for node, entity in sim.topology.nodeAttributes.items():
            for ctrl in self.sink_control:
                if entity["model"] == ctrl["model"]:
                    modules = ctrl["module"]
                    for module in modules if isinstance(modules, list) else [modules]:
                        for _ in range(ctrl["number"]):
                            sim.deploy_sink(app_name, node=node, module=module)
            for ctrl in self.src_control:
                if entity["model"] == ctrl["model"]:
                    for _ in range(ctrl["number"]):
                        sim.deploy_source(
                            app_name, id_node=node, msg=ctrl["message"], distribution=ctrl["distribution"]
                        )


class JSONPopulation(Population):
    """Users read from a population JSON: ``{"sources": [{id_resource, app, message, lambda}]}``.

    Each source emits with exponential inter-arrival times of mean ``lambda`` (YAFS's
    meaning), seeded by ``iteration`` as YAFS does.

    Args:
        json: the parsed JSON or a path to the file.
        iteration: the seed of every source's distribution.
        name: the population's name.
        activation_dist: as in :class:`Population`.

    Raises:
        YAFSInputError: malformed document, or an entry naming an unknown node/app/message.
    """

    def __init__(
        self,
        json: dict[str, Any] | str | os.PathLike[str],
        iteration: int = 1,
        name: str = "JSONPopulation",
        activation_dist: Distribution | None = None,
        logger: logging.Logger | None = None,
    ) -> None:
        super().__init__(name, activation_dist, logger)
        data, self.source = read_json_input(json, "population")
        root = require_mapping(data, self.source, "")
        self.data = root
        self.it = iteration
        self._entries: list[tuple[str, Any, Any, Any, float]] = []
        for index, raw in enumerate(require_list(root, "sources", self.source, "")):
            entry = f"sources[{index}]"
            item = require_mapping(raw, self.source, entry)
            node = require_id(item, "id_resource", self.source, entry)
            app = require_id(item, "app", self.source, entry)
            message = require_id(item, "message", self.source, entry)
            lambd = require_number(item, "lambda", self.source, entry, positive=True)
            self._entries.append((entry, node, app, message, lambd))

    def initial_allocation(self, sim: Sim, app_name: Any) -> None:
        for entry, node, app, message, lambd in self._entries:
            if app != app_name:
                continue
            messages = sim.apps[app_name].messages
            if message not in messages:
                raise YAFSInputError(
                    self.source, entry, "message", f"app {app_name!r} has no source message {message!r}"
                )
            if node not in sim.topology.G:
                raise YAFSInputError(self.source, entry, "id_resource", f"node {node!r} is not in the topology")
            dist = exponential_distribution(lambd, seed=self.it, name="Exp")
            sim.deploy_source(app_name, id_node=node, msg=messages[message], distribution=dist)
