"""The simulation engine (YAFS's ``yafs.core.Sim``), with redundant-dispatch tracking.

Two engines share this class and its public API:

* ``yafs3`` (the default with YAFS's own delay models): YAFS3's event order reproduced
  exactly, so ported scripts write the same rows in the same order as YAFS3 (see
  :mod:`yafs_safetail.yafs._yafs3`).
* ``direct`` (the default when a custom ``link_delay`` or ``service_model`` is given): one
  event per hop end, service end and source tick (see :mod:`yafs_safetail.yafs._direct`).

Both push lightweight events straight onto simpy's own queue (as ``Environment.schedule``
does), so ties keep simpy's deterministic insertion order and user processes (monitors,
placement/population ``run``) interleave normally; :meth:`Sim.run` drives simpy's queue
with its own loop, which is what ``Environment.run`` does minus a call per event.
"""

from __future__ import annotations

import logging
import os
import random
from collections import deque
from collections.abc import Callable
from heapq import heappop, heappush
from typing import Any, cast

import numpy as np
import simpy
from simpy.events import NORMAL, URGENT

from yafs_safetail.yafs._direct import DirectEngine
from yafs_safetail.yafs._records import (
    _FloatTexts,
    _Inline,
    _Lineage,
    _NetPut,
    _Request,
    _StopRun,
    _Until,
)
from yafs_safetail.yafs._yafs3 import YAFS3Engine
from yafs_safetail.yafs.application import Application, Message
from yafs_safetail.yafs.distribution import Distribution, deterministic_distribution
from yafs_safetail.yafs.hooks import LinkDelay, ServiceModel, YAFSLinkDelay, YAFSServiceModel
from yafs_safetail.yafs.metrics import Metrics
from yafs_safetail.yafs.outcomes import CopyOutcome, CopyStatus, RequestOutcome
from yafs_safetail.yafs.placement import Placement
from yafs_safetail.yafs.population import Population
from yafs_safetail.yafs.selection import Selection

__all__ = ["Sim", "RequestOutcome", "CopyOutcome", "EVENT_UP_ENTITY", "EVENT_DOWN_ENTITY",
           "ENGINES"]

RequestListener = Callable[["Sim", RequestOutcome], None]

EVENT_UP_ENTITY = "node_up"
EVENT_DOWN_ENTITY = "node_down"
ENGINES = ("yafs3", "direct")

#: Period of YAFS3's internal stop monitor (it only matters for the process id it takes).
STOP_MONITOR_PERIOD = 200


class Sim(YAFS3Engine, DirectEngine):
    """A YAFS-compatible discrete-event simulation of applications on a topology.

    Args:
        topology: the :class:`~yafs_safetail.yafs.topology.Topology`.
        name_register: accepted for YAFS compatibility, unused.
        link_register: accepted for YAFS compatibility, unused.
        redis: accepted for YAFS compatibility, unused.
        purge_register: accepted for YAFS compatibility, unused.
        logger: a logger (default: this module's).
        default_results_path: results path without extension; ``<path>.csv`` and
            ``<path>_link.csv`` are written (YAFS default ``"result"`` in the working
            directory). The ``yafs3`` engine creates them with the Sim (as YAFS3); the
            ``direct`` engine when :meth:`run` starts.
        link_delay: the hop delay model (default :class:`YAFSLinkDelay`).
        service_model: the admission/service model (default :class:`YAFSServiceModel`).
        seed: seed of :attr:`rng`, the numpy generator behind the ``direct`` engine's
            forwarding filters (``fractional_selectivity``) and broadcast probabilities.
        write_results: False records no result rows (request outcomes still work).
        engine: ``"yafs3"`` (YAFS3's event order, ids and quirks), ``"direct"`` (one event
            per hop, see ``docs/core.md``), or None: ``"yafs3"`` unless a ``link_delay`` or
            ``service_model`` other than YAFS's own is given.
        py_random: the ``random.Random`` behind the ``yafs3`` engine's draws that YAFS3
            takes from Python's global generator (forwarding filters, broadcast
            probabilities); None (YAFS-compatible) uses the global ``random`` module.

    Attributes:
        env: the simpy ``Environment``.
        engine: ``"yafs3"`` or ``"direct"``.
        alloc_DES: process id -> node.
        alloc_module: app -> module -> list of process ids.
        alloc_source: source process id -> ``{"id", "app", "module", "name"}``.
        apps: app name -> :class:`Application`.
        selector_path: app name -> its :class:`Selection`.
        request_listeners: callables ``f(sim, outcome)`` told of every completed request.
        refused_copies: number of copies refused by the service model.
        lost_messages: number of messages dropped (no route, or no such process).
        completed_requests: number of requests whose copies have all settled.
        last_busy_time: directed link -> time until which it is busy (YAFS link queues).
    """

    NODE_METRIC = "COMP_M"
    SOURCE_METRIC = "SRC_M"
    FORWARD_METRIC = "FWD_M"
    SINK_METRIC = "SINK_M"
    LINK_METRIC = "LINK"

    def __init__(
        self,
        topology: Any,
        name_register: str | None = None,
        link_register: str | None = None,
        redis: Any = None,
        purge_register: bool = True,
        logger: logging.Logger | None = None,
        default_results_path: str | os.PathLike[str] | None = None,
        *,
        link_delay: LinkDelay | None = None,
        service_model: ServiceModel | None = None,
        seed: int = 0,
        write_results: bool = True,
        engine: str | None = None,
        py_random: random.Random | None = None,
    ) -> None:
        if engine is None:
            custom = ((link_delay is not None and type(link_delay) is not YAFSLinkDelay)
                      or (service_model is not None and type(service_model) is not YAFSServiceModel))
            engine = "direct" if custom else "yafs3"
        if engine not in ENGINES:
            raise ValueError(f"Sim: engine must be one of {ENGINES}, got {engine!r}")
        self.engine = engine
        self._yafs3 = engine == "yafs3"
        self.env = simpy.Environment()
        self.topology = topology
        self.logger = logger or logging.getLogger(__name__)
        self.metrics = Metrics(default_results_path, enabled=write_results)
        self.rng = np.random.default_rng(seed)
        self._py_random = py_random if py_random is not None else random
        self._py_random_given = py_random is not None
        self.apps: dict[Any, Application] = {}
        self.alloc_DES: dict[int, Any] = {}
        self.alloc_module: dict[Any, dict[str, list[int]]] = {}
        self.alloc_source: dict[int, dict[str, Any]] = {}
        self.selector_path: dict[Any, Any] = {}
        self.placement_policy: dict[str, dict[str, Any]] = {}
        self.population_policy: dict[str, dict[str, Any]] = {}
        self.des_process_running: dict[int, bool] = {}
        self.des_control_process: dict[str, int] = {}
        self.last_busy_time: dict[tuple[Any, Any], float] = {}
        self.request_listeners: list[RequestListener] = []
        self.refused_copies = 0
        self.lost_messages = 0
        self.completed_requests = 0
        self.unreachabled_links = 0  # YAFS attribute, never incremented (as in YAFS)
        self.stop = False
        self.until: float | None = None
        self._id_process = -1
        self._id_message = 0
        self._initialised = False
        # Hot-path shortcuts: row buffers (None = no results) and bound callbacks.
        self._link_rows = self.metrics.link_rows if write_results else None
        self._event_rows = self.metrics.event_rows if write_results else None
        # Events go straight onto simpy's heap, exactly as Environment.schedule puts them.
        self._queue = self.env._queue
        self._eid = self.env._eid
        # direct engine state
        self._replicas: dict[int, Any] = {}
        self._in_flight_hops = 0
        self._hop_end_callbacks = (self._on_hop_end,)
        self._service_end_callbacks = (self._on_service_end,)
        self._source_tick_callbacks = (self._on_source_tick,)
        # yafs3 engine state: the network store, the pipes, transfers in flight.
        self._net_items: deque[Message] = deque()
        self._net_waiting = False
        self._net_alive = False
        self._pump = 0
        self._pipes: dict[tuple[Any, Any, Any], Any] = {}
        self._y_src_start_cbs = (self._y_on_src_start,)
        self._y_src_tick_cbs = (self._y_on_src_tick,)
        self._y_net_put_cbs = (self._y_on_net_put,)
        self._y_net_get_cbs = (self._y_on_net_get,)
        self._y_hop_end_cbs = (self._y_on_hop_end,)
        self._y_pipe_put_cbs = (self._y_on_pipe_put,)
        self._y_proc_start_cbs = (self._y_on_proc_start,)
        self._y_proc_get_cbs = (self._y_on_proc_get,)
        self._y_service_end_cbs = (self._y_on_service_end,)
        self._y_sink_end_cbs = (self._y_on_sink_end,)
        self._net_put_event = _NetPut(self._y_net_put_cbs)
        self._track_by_app: dict[Any, bool] = {}
        # Text of the float values written since the last flush (the yafs3 engine's rows).
        self._float_texts = _FloatTexts()
        self._flush_rows = self.metrics.buffer_rows
        # The event to process next, bypassing the queue (False: only while run's loop runs).
        self._inline_fn: Any = False
        self._inline_ev: Any = None
        self._inline_eid = 0
        if self._yafs3:
            self._start_source = self._y_start_source
            self._start_process = self._y_start_process
        else:
            self._start_source = self._d_start_source
            self._start_process = self._d_start_process
        self.set_link_delay(link_delay or YAFSLinkDelay())
        self.set_service_model(service_model or YAFSServiceModel())
        if self._yafs3:
            # As YAFS3: the result files exist (headers written) once the Sim does.
            self.metrics.open()

    # ----------------------------------------------------------------- configuration

    def set_link_delay(self, link_delay: LinkDelay) -> None:
        """Replace the hop delay model."""
        self.link_delay = link_delay
        self._hop_delay = link_delay.hop_delay_s
        self._link_queues = bool(link_delay.uses_link_queues)
        # YAFS's own formula is inlined by the yafs3 engine (same arithmetic, no call).
        self._y_inline_delay = type(link_delay) is YAFSLinkDelay

    def set_service_model(self, service_model: ServiceModel) -> None:
        """Replace the admission/service model.

        Raises:
            ValueError: a concurrent service model with the ``yafs3`` engine (YAFS3 serves
                one message at a time per replica; use ``engine="direct"``).
        """
        if self._yafs3 and service_model.concurrent:
            raise ValueError("Sim: the yafs3 engine serves one message at a time per replica; "
                             "a concurrent service model needs engine='direct'")
        self.service_model = service_model
        self._concurrent = bool(service_model.concurrent)
        self._admit = service_model.admit
        self._service_time = service_model.service_time_s
        self._release = service_model.release
        self._y_inline_service = type(service_model) is YAFSServiceModel

    @property
    def network_pump(self) -> int:
        """Hop transfers in flight now (YAFS's name; the ``buffer`` column counts these)."""
        return self._pump if self._yafs3 else self._in_flight_hops

    @property
    def entity_metrics(self) -> dict[str, dict[Any, dict[str, Any]]]:
        """YAFS's ``{"node": {id: {}}, "link": {edge: {"PR", "BW"}}}`` of the topology."""
        graph = self.topology.G
        return {"node": {node: {} for node in self.topology.get_nodes_att()},
                "link": {edge: {"PR": graph.edges[edge]["PR"], "BW": graph.edges[edge]["BW"]}
                         for edge in graph.edges}}

    # ----------------------------------------------------------------- ids

    def _new_process_id(self) -> int:
        self._id_process += 1
        return self._id_process

    def _new_message_id(self) -> int:
        self._id_message += 1
        return self._id_message

    # ----------------------------------------------------------------- request outcomes

    def _lineage_message_done(self, lineage: _Lineage) -> None:
        lineage.live -= 1
        if lineage.live <= 0 and lineage.status is None:
            if lineage.refused:
                lineage.status = "refused"
            elif lineage.lost:
                lineage.status = "lost"
            else:
                lineage.status = "consumed"
            lineage.time_end = self.env._now
            self._settle(lineage)

    def _message_lost(self, msg: Message) -> None:
        """``msg`` goes no further (no route, or no process to take it), in either engine."""
        self.lost_messages += 1
        lineage = msg._lineage
        if lineage is not None:
            lineage.lost = True
            self._lineage_message_done(lineage)

    def _settle(self, lineage: _Lineage) -> None:
        request = lineage.request
        request.unsettled -= 1
        if request.unsettled == 0:
            self._complete(request)

    def _complete(self, request: _Request) -> None:
        # Every lineage of a complete request has settled: its status is set.
        copies = [CopyOutcome(lin.copy_index, lin.dst_node, lin.des, cast(CopyStatus, lin.status), lin.time_end)
                  for lin in request.lineages]
        first = None
        for copy in copies:
            if copy.status == "answered" and (first is None or copy.time_end < first.time_end):
                first = copy
        outcome = RequestOutcome(request.request_id, request.app_name, request.time_emit, copies,
                                 first, request.src_des, request.src_node)
        self.completed_requests += 1
        hook = getattr(request.selection, "on_request_complete", None)
        if hook is not None:
            hook(self, outcome)
        for listener in self.request_listeners:
            listener(self, outcome)


    # ----------------------------------------------------------------- control processes

    def _control_process(self, policy: Any, kind: str):
        # As YAFS: the process takes its id when it starts (at the first event), not when
        # it is created.
        my_id = self._new_process_id()
        self.des_process_running[my_id] = True
        self.des_control_process[policy.name] = my_id
        self.logger.debug("Added control process for %s %s (#DES:%i)", kind, policy.name, my_id)
        while not self.stop and self.des_process_running[my_id]:
            yield self.env.timeout(policy.get_next_activation())
            policy.run(self)

    def _monitor_process(self, des: int, function: Callable[..., Any], distribution: Distribution,
                         param: dict[str, Any]):
        while not self.stop and self.des_process_running[des]:
            yield self.env.timeout(distribution.next())
            function(**param)

    def _stop_monitor_process(self):
        """YAFS3's internal stop monitor: it takes a process id when it starts (so every id
        taken during the run is one higher than it would otherwise be) and sets
        :attr:`stop` once ``until`` is reached. With ``until=None`` it ends at once (YAFS's
        would keep the simulation running forever)."""
        self._new_process_id()
        period = deterministic_distribution(STOP_MONITOR_PERIOD, name="SIM_Deterministic")
        while not self.stop and self.until:
            yield self.env.timeout(period.next())
            if self.until and self.env.now >= self.until:
                self.stop = True

    def _entity_event_process(self, next_event: Callable[..., float], param: dict[str, Any],
                              down: bool):
        """YAFS's placeholder up/down entity processes: they take an id and only wait."""
        my_id = self._new_process_id()
        if down:
            self.des_process_running[my_id] = True
        while not self.stop and (not down or self.des_process_running[my_id]):
            yield self.env.timeout(next_event(**param))

    # ----------------------------------------------------------------- public API

    def deploy_app(self, app: Application, placement: Placement, *args: Any, **kwargs: Any) -> None:
        """Register an application with its placement and selection.

        Both YAFS forms are accepted: ``deploy_app(app, placement, selector)`` (YAFS3) and
        ``deploy_app(app, placement, population, selector)`` (older YAFS); ``selector=``
        and ``population=`` may also be given as keywords.
        """
        population = kwargs.pop("population", None)
        selector = kwargs.pop("selector", None)
        if kwargs:
            raise TypeError(f"deploy_app got unexpected keyword arguments {sorted(kwargs)}")
        if len(args) == 2:
            population, selector = args
        elif len(args) == 1:
            if selector is None:
                selector = args[0]
            else:
                population = args[0]
        elif args:
            raise TypeError("deploy_app takes (app, placement, selector) or (app, placement, population, selector)")
        if selector is None:
            raise TypeError("deploy_app needs a selector")
        self.apps[app.name] = app
        self.alloc_module.setdefault(app.name, {})
        if placement.name not in self.placement_policy:
            self.placement_policy[placement.name] = {"placement_policy": placement, "apps": []}
            if placement.activation_dist is not None:
                self.env.process(self._control_process(placement, "placement"))
        self.placement_policy[placement.name]["apps"].append(app.name)
        if population is not None:
            if population.name not in self.population_policy:
                self.population_policy[population.name] = {"population_policy": population, "apps": []}
                if population.activation_dist is not None:
                    self.env.process(self._control_process(population, "population"))
            self.population_policy[population.name]["apps"].append(app.name)
        self.selector_path[app.name] = selector
        self._track_by_app.pop(app.name, None)

    def deploy_app2(self, app: Application, placement: Placement, population: Population,
                    selector: Selection) -> None:
        """The 4-argument form under YAFS3's name for it."""
        self.deploy_app(app, placement, population, selector)

    def deploy_source(self, app_name: Any, id_node: Any, msg: Message, distribution: Distribution) -> int:
        """Add a user on ``id_node`` emitting ``msg`` at ``distribution``'s times; return its id."""
        des = self._new_process_id()
        self.des_process_running[des] = True
        self.alloc_DES[des] = id_node
        self.alloc_source[des] = {"id": id_node, "app": app_name, "module": msg.src, "name": msg.name}
        self._start_source(des, app_name, msg, distribution, True)
        return des

    def deploy_module(self, app_name: Any, module: str, services: list[dict[str, Any]],
                      ids: list[Any]) -> list[int]:
        """Deploy one replica of ``module`` (with its ``services``) on each node of ``ids``.

        A module's source services (``add_service_source``) get their own processes first,
        one per node, then one replica process per node, as in YAFS.
        """
        registers = []
        deployed: list[int] = []
        for service in services:
            if service["type"] == Application.TYPE_SOURCE:
                for node in ids:
                    des = self._new_process_id()
                    self.des_process_running[des] = True
                    self.alloc_DES[des] = node
                    self._start_source(des, app_name, service["message_out"], service["dist"], False)
                    deployed.append(des)
            else:
                registers.append(service)
        if registers:
            for node in ids:
                des = self._new_process_id()
                self.des_process_running[des] = True
                self.alloc_DES[des] = node
                self._start_process(des, app_name, module, registers, False)
                self.alloc_module.setdefault(app_name, {}).setdefault(module, []).append(des)
                deployed.append(des)
        return deployed

    def deploy_sink(self, app_name: Any, node: Any, module: str) -> int:
        """Add a sink (actuator) of ``module`` on ``node``; return its process id."""
        des = self._new_process_id()
        self.des_process_running[des] = True
        self.alloc_DES[des] = node
        self._start_process(des, app_name, module, [], True)
        self.alloc_module.setdefault(app_name, {}).setdefault(module, []).append(des)
        return des

    def deploy_monitor(self, name: str, function: Callable[..., Any], distribution: Distribution,
                       **param: Any) -> int:
        """Call ``function(**param)`` at ``distribution``'s times; return the process id."""
        des = self._new_process_id()
        self.des_process_running[des] = True
        self.des_control_process[name] = des
        self.env.process(self._monitor_process(des, function, distribution, param))
        return des

    def register_event_entity(self, next_event_dist: Callable[..., float],
                              event_type: str = EVENT_UP_ENTITY, **args: Any) -> None:
        """YAFS's entity up/down processes: each takes a process id when it starts and waits
        ``next_event_dist(**args)`` in a loop; like YAFS3's, they change nothing else."""
        if event_type == EVENT_UP_ENTITY:
            self.env.process(self._entity_event_process(next_event_dist, args, down=False))
        elif event_type == EVENT_DOWN_ENTITY:
            self.env.process(self._entity_event_process(next_event_dist, args, down=True))

    def stop_process(self, id: int) -> None:  # noqa: A002 - YAFS name
        """Stop a process (a source stops emitting; a replica stops taking messages).

        With the ``yafs3`` engine a replica waiting on its pipe still serves the next
        message that arrives, then ends, as YAFS's process does.
        """
        self.des_process_running[id] = False

    def start_process(self, id: int) -> None:  # noqa: A002 - YAFS name
        """Mark a process as running again (YAFS semantics: an ended source loop stays ended)."""
        self.des_process_running[id] = True

    def get_DES(self, name: str) -> int:  # noqa: N802 - YAFS name
        """Process id of a control process or monitor by name."""
        return self.des_control_process[name]

    def undeploy_module(self, app_name: Any, service_name: str, des: int) -> None:
        """Remove one replica."""
        replicas = self.alloc_module[app_name][service_name]
        if des in replicas:
            replicas.remove(des)
            self.stop_process(des)
            del self.alloc_DES[des]

    def undeploy_all_modules(self, app_name: Any, service_name: str, idtopo: Any) -> None:
        """Remove the replicas of ``service_name`` on node ``idtopo``.

        ``yafs3`` engine: YAFS3's loop, which removes from the list it walks and so skips
        the replica after each one it removes (two adjacent replicas on the node: one
        stays). ``direct`` engine: every replica on the node is removed.
        """
        on_node = [des for des, node in self.alloc_DES.items() if node == idtopo]
        replicas = self.alloc_module[app_name][service_name]
        if self._yafs3:
            for des in replicas:
                if des in on_node:
                    replicas.remove(des)
                    self.stop_process(des)
                    del self.alloc_DES[des]
            return
        for des in [d for d in replicas if d in on_node]:
            replicas.remove(des)
            self.stop_process(des)
            del self.alloc_DES[des]

    def undeploy_source(self, des: int) -> None:
        """Remove one source."""
        if des in self.alloc_source:
            self.stop_process(des)
            del self.alloc_source[des]
            del self.alloc_DES[des]

    def remove_node(self, id_node_topology: Any) -> None:
        """Stop processes on a node and remove the node from the topology.

        ``yafs3`` engine: as YAFS3, only the *first* process found on the node is stopped
        and forgotten (the others keep their allocation; sources stay in
        :attr:`alloc_source`). ``direct`` engine: every process on the node.

        Raises:
            networkx.NetworkXError: the node is not in the graph (as YAFS).
        """
        if self._yafs3:
            removed = []
            for des, node in self.alloc_DES.items():
                if node == id_node_topology:
                    removed.append(des)
                    break
            for des in removed:
                self.stop_process(des)
                del self.alloc_DES[des]
            for modules in self.alloc_module.values():
                for replicas in modules.values():
                    for des in removed:
                        if des in replicas:
                            replicas.remove(des)
            self.topology.G.remove_node(id_node_topology)
            return
        removed = [des for des, node in self.alloc_DES.items() if node == id_node_topology]
        for des in removed:
            self.stop_process(des)
            del self.alloc_DES[des]
            self.alloc_source.pop(des, None)
        for modules in self.alloc_module.values():
            for replicas in modules.values():
                replicas[:] = [des for des in replicas if des not in removed]
        self.topology.G.remove_node(id_node_topology)

    def get_alloc_entities(self) -> dict[Any, list[str]]:
        """Node -> list of ``"app#module"`` deployed on it.

        ``yafs3`` engine: YAFS3's table, whose sources are listed on the node they were
        deployed on (``alloc_source[des]["id"]``) and which raises ``KeyError`` when that
        node is no longer in the graph. ``direct`` engine: sources on their current node,
        nodes outside the graph added as needed.
        """
        entities: dict[Any, list[str]] = {node: [] for node in self.topology.G.nodes}
        if self._yafs3:
            for src in self.alloc_source.values():
                entities[src["id"]].append(f"{src['app']}#{src['module']}")
            for app, modules in self.alloc_module.items():
                for module, replicas in modules.items():
                    for des in replicas:
                        entities[self.alloc_DES[des]].append(f"{app}#{module}")
            return entities
        for des, src in self.alloc_source.items():
            entities.setdefault(self.alloc_DES.get(des, src["id"]), []).append(f"{src['app']}#{src['module']}")
        for app, modules in self.alloc_module.items():
            for module, replicas in modules.items():
                for des in replicas:
                    entities.setdefault(self.alloc_DES[des], []).append(f"{app}#{module}")
        return entities

    def get_DES_from_Service_In_Node(self, node: Any, app_name: Any, service: str) -> Any:  # noqa: N802
        """The first replica of ``service`` on ``node``, or ``[]`` (YAFS)."""
        for des in self.alloc_module[app_name][service]:
            if self.alloc_DES[des] == node:
                return des
        return []

    def get_assigned_structured_modules_from_DES(self) -> dict[int, dict[str, Any]]:
        """Process id -> ``{"DES": node, "module": module}`` for every replica and sink."""
        return {des: {"DES": self.alloc_DES[des], "module": module}
                for modules in self.alloc_module.values()
                for module, replicas in modules.items() for des in replicas}

    def print_debug_assignaments(self) -> None:  # YAFS spelling
        """Print the table process id | node | source message | module."""
        modules = {des: info["module"] for des, info in self.get_assigned_structured_modules_from_DES().items()}
        print("-" * 40)
        print("DES\t| TOPO \t| Src.Mod \t| Modules")
        print("-" * 40)
        for des, node in self.alloc_DES.items():
            src = self.alloc_source[des]["name"] if des in self.alloc_source else "--"
            print(des, "\t|", node, "\t|", src, "\t\t|", modules.get(des, "--"))
        print("-" * 40)

    def run(self, until: float | None, show_progress_monitor: bool = False,
            test_initial_deploy: bool = False) -> None:
        """Run the simulation until time ``until`` (events at exactly ``until`` do not run).

        The first call performs the populations' and placements' initial allocations (in
        that order, as YAFS does); with the ``yafs3`` engine it then starts YAFS3's
        internal stop monitor and prints the assignment table, as YAFS3's ``run`` does.
        Later calls continue the same simulation (YAFS3 supports one call). Result files
        are flushed and closed at the end of each call (a later call appends).

        Args:
            until: the stop time; ``None`` runs until no event is left.
            show_progress_monitor: accepted for YAFS compatibility, unused.
            test_initial_deploy: only perform the initial allocation.
        """
        self.metrics.open()
        if not self._initialised:
            self._initialised = True
            if self._yafs3:
                # YAFS's network process starts first, with an empty busy-link table.
                self._net_alive = True
                self._net_waiting = True
                self.last_busy_time = {}
            for policy in self.population_policy.values():
                for app_name in policy["apps"]:
                    policy["population_policy"].initial_allocation(self, app_name)
            for policy in self.placement_policy.values():
                validate = getattr(policy["placement_policy"], "validate_apps", None)
                if validate is not None:
                    validate(self.apps)
                for app_name in policy["apps"]:
                    policy["placement_policy"].initial_allocation(self, app_name)
            if self._yafs3:
                self.until = until
                self.env.process(self._stop_monitor_process())
                self.print_debug_assignaments()
        self.until = until
        try:
            if not test_initial_deploy:
                self._run_events(until)
        finally:
            self.metrics.close()

    def _run_events(self, until: float | None) -> None:
        """simpy's ``Environment.run(until)``, step for step, in one loop.

        An engine callback whose last act is to schedule a zero-delay event while nothing
        else is due at this instant leaves it in ``_inline_fn``/``_inline_ev`` (with the id
        it would have had) instead of pushing it: it is the next event either way, so the
        loop runs it at once. Should anything reach the queue for this instant in between,
        the event goes back into the queue and the usual order decides.
        """
        env = self.env
        queue = self._queue
        if until is not None:
            at = until if isinstance(until, int) else float(until)
            if at <= env._now:
                raise ValueError(f"until ({at}) must be greater than the current simulation time")
            # As simpy: an urgent event at ``until``, scheduled before anything it stops.
            heappush(queue, (env._now + (at - env._now), URGENT, next(self._eid), _Until()))
        pop = heappop
        self._inline_fn = None
        try:
            while True:
                fn = self._inline_fn
                if fn is not None:
                    self._inline_fn = None
                    event = self._inline_ev
                    now = env._now
                    if queue and queue[0][0] <= now and queue[0] < (now, NORMAL, self._inline_eid):
                        # Something was queued for this instant meanwhile and goes first.
                        heappush(queue, (now, NORMAL, self._inline_eid, _Inline(fn, event)))
                    else:
                        fn(event)
                        continue
                if not queue:
                    break
                env._now, _, _, event = pop(queue)
                callbacks = event.callbacks
                if callbacks.__class__ is tuple:
                    # The engines' own events: one callback, set again before each push.
                    callbacks[0](event)
                    continue
                event.callbacks = None
                for callback in callbacks:
                    callback(event)
                if not event._ok and not hasattr(event, "_defused"):
                    exc = type(event._value)(*event._value.args)
                    exc.__cause__ = event._value
                    raise exc
        except _StopRun:
            pass
        finally:
            if self._inline_fn:
                heappush(queue, (env._now, NORMAL, self._inline_eid,
                                 _Inline(self._inline_fn, self._inline_ev)))
            self._inline_fn = False
