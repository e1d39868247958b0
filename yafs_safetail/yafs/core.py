"""The simulation engine (YAFS's ``yafs.core.Sim``), with redundant-dispatch tracking.

Hot path design: no simpy process per message or hop. Every hop end, service end and
source tick is one lightweight event pushed on simpy's own queue (``env.schedule``) with a
bound-method callback, so ties keep simpy's deterministic insertion order and user
processes (monitors, placement/population ``run``) interleave normally.
"""

from __future__ import annotations

import logging
import os
from collections import deque
from collections.abc import Callable
from heapq import heappush
from typing import Any

import numpy as np
import simpy
from simpy.events import NORMAL

from yafs_safetail.yafs.application import Application, Message
from yafs_safetail.yafs.distribution import Distribution
from yafs_safetail.yafs.hooks import LinkDelay, ServiceModel, YAFSLinkDelay, YAFSServiceModel
from yafs_safetail.yafs.metrics import Metrics
from yafs_safetail.yafs.outcomes import CopyOutcome, RequestOutcome
from yafs_safetail.yafs.placement import Placement
from yafs_safetail.yafs.population import Population
from yafs_safetail.yafs.selection import Selection

__all__ = ["Sim", "RequestOutcome", "CopyOutcome"]

RequestListener = Callable[["Sim", RequestOutcome], None]


class _Wake:
    """A minimal simpy-compatible event: simpy's step only needs these attributes.

    ``callbacks`` is a shared one-element tuple (simpy only iterates it), so an event
    costs one small allocation.
    """

    __slots__ = ("callbacks", "_ok", "_value", "item", "aux")

    def __init__(self, callbacks: tuple[Callable[[_Wake], None]], item: Any, aux: Any = None) -> None:
        self.callbacks = callbacks
        self._ok = True
        self._value = None
        self.item = item
        self.aux = aux


class _Request:
    """Tracking record of one source-emitted request."""

    __slots__ = ("request_id", "app_name", "time_emit", "selection", "lineages", "unsettled",
                 "src_des", "src_node")

    def __init__(self, request_id: int, app_name: Any, time_emit: float, selection: Any,
                 src_des: Any, src_node: Any) -> None:
        self.request_id = request_id
        self.app_name = app_name
        self.time_emit = time_emit
        self.selection = selection
        self.lineages: list[_Lineage] = []
        self.unsettled = 0
        self.src_des = src_des
        self.src_node = src_node


class _Lineage:
    """One copy of a request and every message derived from it.

    ``live`` counts the lineage's messages still in the system; the copy settles when
    the first of them reaches a sink (answered) or when ``live`` drops to zero.
    """

    __slots__ = ("request", "copy_index", "dst_node", "des", "live", "status", "time_end",
                 "refused", "lost")

    def __init__(self, request: _Request, copy_index: int, dst_node: Any, des: Any) -> None:
        self.request = request
        self.copy_index = copy_index
        self.dst_node = dst_node
        self.des = des
        self.live = 0
        self.status: str | None = None
        self.time_end = 0.0
        self.refused = False
        self.lost = False


class _Replica:
    """A module replica or sink: one DES process id with its FIFO queue.

    ``outputs`` maps each accepted message name to its transmission rules
    ``(message_out, filter, filter_params, module_dest, p)``, in registration order.
    """

    __slots__ = ("des", "app_name", "module", "outputs", "is_sink", "queue", "busy")

    def __init__(self, des: int, app_name: Any, module: str,
                 registers: list[dict[str, Any]], is_sink: bool) -> None:
        self.des = des
        self.app_name = app_name
        self.module = module
        self.outputs: dict[str, list[tuple[Any, Any, dict[str, Any], list[str], list[float]]]] = {}
        for register in registers:
            self.outputs.setdefault(register["message_in"].name, []).append((
                register["message_out"], register["dist"], register.get("param", {}),
                register.get("module_dest") or [], register.get("p") or [],
            ))
        self.is_sink = is_sink
        self.queue: deque[Message] = deque()
        self.busy = False


class _Source:
    """A pure source (user) or a module's periodic source service."""

    __slots__ = ("des", "app_name", "message", "distribution")

    def __init__(self, des: int, app_name: Any, message: Message, distribution: Distribution) -> None:
        self.des = des
        self.app_name = app_name
        self.message = message
        self.distribution = distribution


class Sim:
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
            directory). The files are opened when :meth:`run` starts.
        link_delay: the hop delay model (default :class:`YAFSLinkDelay`).
        service_model: the admission/service model (default :class:`YAFSServiceModel`).
        seed: seed of :attr:`rng`, the generator behind forwarding filters such as
            ``fractional_selectivity`` and broadcast probabilities.
        write_results: False records no result rows (request outcomes still work).

    Attributes:
        env: the simpy ``Environment``.
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
    ) -> None:
        self.env = simpy.Environment()
        self.topology = topology
        self.logger = logger or logging.getLogger(__name__)
        self.metrics = Metrics(default_results_path, enabled=write_results)
        self.rng = np.random.default_rng(seed)
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
        self.stop = False
        self.until: float | None = None
        self._id_process = -1
        self._id_message = 0
        self._replicas: dict[int, _Replica] = {}
        self._in_flight_hops = 0
        self._initialised = False
        # Hot-path shortcuts: row buffers (None = no results) and bound callbacks.
        self._link_rows = self.metrics.link_rows if write_results else None
        self._event_rows = self.metrics.event_rows if write_results else None
        self._hop_end_callbacks = (self._on_hop_end,)
        self._service_end_callbacks = (self._on_service_end,)
        self._source_tick_callbacks = (self._on_source_tick,)
        # Events go straight onto simpy's heap, exactly as Environment.schedule puts them.
        self._queue = self.env._queue
        self._eid = self.env._eid
        self.set_link_delay(link_delay or YAFSLinkDelay())
        self.set_service_model(service_model or YAFSServiceModel())

    # ----------------------------------------------------------------- configuration

    def set_link_delay(self, link_delay: LinkDelay) -> None:
        """Replace the hop delay model."""
        self.link_delay = link_delay
        self._hop_delay = link_delay.hop_delay_s
        self._link_queues = bool(link_delay.uses_link_queues)

    def set_service_model(self, service_model: ServiceModel) -> None:
        """Replace the admission/service model."""
        self.service_model = service_model
        self._concurrent = bool(service_model.concurrent)
        self._admit = service_model.admit
        self._service_time = service_model.service_time_s
        self._release = service_model.release

    # ----------------------------------------------------------------- ids

    def _new_process_id(self) -> int:
        self._id_process += 1
        return self._id_process

    def _new_message_id(self) -> int:
        self._id_message += 1
        return self._id_message

    # ----------------------------------------------------------------- sending

    def _emit_request(self, source: _Source) -> None:
        """A source emits a new request: a fresh id, then one copy per returned path."""
        msg = source.message.clone()
        now = self.env._now
        msg.timestamp = now
        msg.id = self._new_message_id()
        msg.original_DES_src = source.des
        msg.last_idDes = []
        app_name = source.app_name
        request = _Request(msg.id, app_name, now, self.selector_path.get(app_name), source.des,
                           self.alloc_DES.get(source.des))
        self._send(app_name, msg, source.des, request, None)

    def _send(self, app_name: Any, msg: Message, from_des: int, request: _Request | None,
              lineage: _Lineage | None) -> int:
        """Route ``msg`` with the app's selection and start every copy; return the count.

        For a source-emitted request (``request`` given) each path starts a new lineage;
        for a derived message the copies join the sender's ``lineage``.
        """
        selection = self.selector_path[app_name]
        try:
            paths, des_list = selection.get_path(
                self, app_name, msg, self.alloc_DES[from_des], self.alloc_DES, self.alloc_module,
                self.last_busy_time, from_des=from_des,
            )
        except KeyError as exc:
            # YAFS treats a missing allocation as an unreachable destination, not a crash.
            self.logger.warning("(#DES:%s) unreachable destination for %s: KeyError %s",
                                from_des, msg.name, exc)
            paths, des_list = [], []
        if des_list and (des_list[0] is None or des_list[0] == []):
            paths, des_list = [], []
        count = len(paths)
        if request is not None:
            request.unsettled = count
            lineages = request.lineages
            for index in range(count):
                lineages.append(_Lineage(request, index, paths[index][-1], des_list[index]))
            if count == 0:
                self.lost_messages += 1
                self._complete(request)
                return 0
        elif lineage is not None:
            lineage.live += count
            if count == 0:
                lineage.lost = True
        if count == 0:
            self.lost_messages += 1
            return 0
        forward = self._forward
        # ``msg`` is always a fresh object here, so it serves as the first copy; the other
        # copies are cloned before any copy moves (delivery may mutate it).
        copies = [msg]
        if count > 1:
            copies += [msg.clone() for _ in range(count - 1)]
        for index in range(count):
            path = paths[index]
            copy = copies[index]
            copy.path = path
            copy.app_name = app_name
            copy.idDES = des_list[index]
            copy._hop = 0
            copy.dst_int = -1
            if request is not None:
                own = request.lineages[index]
                own.live = 1
                copy._lineage = own
                copy.copy_index = index
                copy.copy_dst_node = path[-1]
            forward(copy)
        return count

    def _forward(self, msg: Message) -> None:
        """Start the next hop of ``msg``, or deliver it if it is at the end of its path."""
        path = msg.path
        hop = msg._hop
        if hop >= len(path) - 1:
            self._deliver(msg)
            return
        src = path[hop]
        dst = path[hop + 1]
        msg.dst_int = dst
        try:
            latency = self._hop_delay(self, msg, src, dst)
        except KeyError:
            self._reroute(msg, src, dst)
            return
        now = self.env._now
        if self._link_queues:
            busy = self.last_busy_time
            link = (src, dst)
            last_used = busy.get(link, 0.0)
            # YAFS's arithmetic, kept term for term so that times match its traces exactly.
            if last_used < now:
                delay = latency
                busy[link] = latency + now
            else:
                shift = last_used - now
                delay = latency + shift
                busy[link] = now + shift + latency
        else:
            delay = latency
        rows = self._link_rows
        if rows is not None:
            rows.append((msg.id, "LINK", src, dst, msg.app_name, latency, msg.name, now,
                         msg.bytes, self._in_flight_hops))
        self._in_flight_hops += 1
        # The message itself is the hop-end event (see Message: simpy needs callbacks/_ok).
        msg.callbacks = self._hop_end_callbacks
        heappush(self._queue, (now + delay, NORMAL, next(self._eid), msg))

    def _on_hop_end(self, msg: Message) -> None:
        self._in_flight_hops -= 1
        hop = msg._hop = msg._hop + 1
        if hop >= len(msg.path) - 1:
            self._deliver(msg)
        else:
            self._forward(msg)

    def _reroute(self, msg: Message, src: Any, dst: Any) -> None:
        """The link ``src -> dst`` is gone: ask the selection for another path (YAFS)."""
        self.logger.warning("link (%s, %s) unreachable at %s; re-routing %s", src, dst,
                            self.env._now, msg.name)
        selection = self.selector_path[msg.app_name]
        paths, des_list = selection.get_path_from_failure(
            self, msg, (src, dst), self.alloc_DES, self.alloc_module, self.last_busy_time,
            self.env._now, from_des=msg.idDES,
        )
        new_path = paths[0] if paths else None
        if not new_path or src not in new_path or (
            new_path.index(src) + 1 < len(new_path) and new_path[new_path.index(src) + 1] == dst
        ):
            self._drop(msg)
            return
        msg.path = new_path
        msg.idDES = des_list[0]
        msg._hop = new_path.index(src)
        self._forward(msg)

    def _drop(self, msg: Message) -> None:
        self.lost_messages += 1
        lineage = msg._lineage
        if lineage is not None:
            lineage.lost = True
            self._lineage_message_done(lineage)

    # ----------------------------------------------------------------- modules and sinks

    def _deliver(self, msg: Message) -> None:
        """``msg`` reached its destination node: hand it to its process."""
        now = self.env._now
        msg.timestamp_rec = now
        replica = self._replicas.get(msg.idDES)
        if replica is None or not self.des_process_running.get(replica.des, False):
            self._drop(msg)
            return
        if replica.is_sink:
            self._record(replica, msg, self.SINK_METRIC, 0, now)
            lineage = msg._lineage
            if lineage is not None:
                if lineage.status is None:
                    lineage.status = "answered"
                    lineage.time_end = now
                    self._settle(lineage)
                self._lineage_message_done(lineage)
            return
        if msg.name not in replica.outputs:
            # YAFS: a replica ignores messages none of its transmissions consume.
            self._drop(msg)
            return
        node = self.alloc_DES[replica.des]
        if not self._admit(self, msg, replica.des, node, replica.module):
            self.refused_copies += 1
            lineage = msg._lineage
            if lineage is not None:
                lineage.refused = True
                self._lineage_message_done(lineage)
            return
        if self._concurrent:
            self._start_service(replica, msg)
        elif replica.busy:
            replica.queue.append(msg)
        else:
            self._start_service(replica, msg)

    def _start_service(self, replica: _Replica, msg: Message) -> None:
        replica.busy = True
        node = self.alloc_DES[replica.des]
        service = self._service_time(self, msg, replica.des, node, replica.module)
        self._record(replica, msg, self.NODE_METRIC, service, self.env._now)
        heappush(self._queue, (self.env._now + service, NORMAL, next(self._eid),
                               _Wake(self._service_end_callbacks, msg, replica)))

    def _on_service_end(self, event: _Wake) -> None:
        msg = event.item
        replica = event.aux
        node = self.alloc_DES.get(replica.des)
        self._release(self, msg, replica.des, node, replica.module)
        self._emit_outputs(replica, msg)
        if not self._concurrent:
            replica.busy = False
            if replica.queue:
                self._start_service(replica, replica.queue.popleft())

    def _emit_outputs(self, replica: _Replica, msg: Message) -> None:
        """Send every output ``msg`` triggers at ``replica`` (YAFS transmission rules)."""
        lineage = msg._lineage
        if self.des_process_running.get(replica.des, False):
            for out, dist, param, destinations, probabilities in replica.outputs[msg.name]:
                if not out:
                    continue
                if dist and not self._accepts(dist, param):
                    continue
                if not destinations:
                    self._send(replica.app_name, self._derive(out, msg, replica.des), replica.des,
                               None, lineage)
                    continue
                for index, module_dst in enumerate(destinations):
                    if self.rng.random() <= probabilities[index]:
                        derived = self._derive(out, msg, replica.des)
                        derived.dst = module_dst
                        self._send(replica.app_name, derived, replica.des, None, lineage)
        if lineage is not None:
            self._lineage_message_done(lineage)

    def _accepts(self, dist: Callable[..., bool], param: dict[str, Any]) -> bool:
        if getattr(dist, "wants_rng", False) and "rng" not in param:
            return bool(dist(rng=self.rng, **param))
        return bool(dist(**param))

    def _derive(self, template: Message, parent: Message, des: int) -> Message:
        """A module's output message: inherits the request id and the copy lineage."""
        out = template.clone()
        out.timestamp = self.env._now
        out.id = parent.id
        out.original_DES_src = parent.original_DES_src
        out.last_idDes = [*parent.last_idDes, des]
        out.copy_index = parent.copy_index
        out.copy_dst_node = parent.copy_dst_node
        out._lineage = parent._lineage
        return out

    def _record(self, replica: _Replica, msg: Message, kind: str, service: float, now: float) -> None:
        rows = self._event_rows
        if rows is None:
            return
        app_name = replica.app_name
        path = msg.path
        src_des = msg.original_DES_src
        senders = self.alloc_module[app_name].get(msg.src) if path else None
        if senders is not None:
            # YAFS's rule: the last replica of the sending module on the path's first node.
            src_des = -1
            first = path[0]
            alloc = self.alloc_DES
            for des in reversed(senders):
                if alloc.get(des) == first:
                    src_des = des
                    break
        rows.append((msg.id, kind, app_name, replica.module, msg.name, src_des, replica.des,
                     path[0] if path else None, self.alloc_DES[replica.des], msg.src, service,
                     now, service + now, float(msg.timestamp), float(msg.timestamp_rec)))

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

    def _settle(self, lineage: _Lineage) -> None:
        request = lineage.request
        request.unsettled -= 1
        if request.unsettled == 0:
            self._complete(request)

    def _complete(self, request: _Request) -> None:
        copies = [CopyOutcome(lin.copy_index, lin.dst_node, lin.des, lin.status, lin.time_end)
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

    # ----------------------------------------------------------------- sources

    def _schedule_source(self, source: _Source) -> None:
        self.env.schedule(_Wake(self._source_tick_callbacks, source), NORMAL, source.distribution.next())

    def _on_source_tick(self, event: _Wake) -> None:
        source = event.item
        rows = self._link_rows
        # Buffers are checked once per emitted request rather than once per row.
        if rows is not None and len(rows) + len(self._event_rows) >= self.metrics.buffer_rows:
            self.metrics.flush()
        running = self.des_process_running
        if running.get(source.des, False):
            self._emit_request(source)
        if not self.stop and running.get(source.des, False):
            self._schedule_source(source)

    # ----------------------------------------------------------------- control processes

    def _control_process(self, policy: Any, kind: str):
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
        self._schedule_source(_Source(des, app_name, msg, distribution))
        return des

    def deploy_module(self, app_name: Any, module: str, services: list[dict[str, Any]],
                      ids: list[Any]) -> list[int]:
        """Deploy one replica of ``module`` (with its ``services``) on each node of ``ids``."""
        registers = []
        deployed: list[int] = []
        for service in services:
            if service["type"] == Application.TYPE_SOURCE:
                for node in ids:
                    des = self._new_process_id()
                    self.des_process_running[des] = True
                    self.alloc_DES[des] = node
                    self._schedule_source(_Source(des, app_name, service["message_out"], service["dist"]))
                    deployed.append(des)
            else:
                registers.append(service)
        if registers:
            for node in ids:
                des = self._new_process_id()
                self.des_process_running[des] = True
                self.alloc_DES[des] = node
                self._replicas[des] = _Replica(des, app_name, module, registers, is_sink=False)
                self.alloc_module.setdefault(app_name, {}).setdefault(module, []).append(des)
                deployed.append(des)
        return deployed

    def deploy_sink(self, app_name: Any, node: Any, module: str) -> int:
        """Add a sink (actuator) of ``module`` on ``node``; return its process id."""
        des = self._new_process_id()
        self.des_process_running[des] = True
        self.alloc_DES[des] = node
        self._replicas[des] = _Replica(des, app_name, module, [], is_sink=True)
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

    def stop_process(self, id: int) -> None:  # noqa: A002 - YAFS name
        """Stop a process (a source stops emitting; a replica stops accepting messages)."""
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

    def undeploy_source(self, des: int) -> None:
        """Remove one source."""
        if des in self.alloc_source:
            self.stop_process(des)
            del self.alloc_source[des]
            del self.alloc_DES[des]

    def remove_node(self, id_node_topology: Any) -> None:
        """Stop every process on a node and remove the node from the topology."""
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
        """Node -> list of ``"app#module"`` deployed on it."""
        entities: dict[Any, list[str]] = {node: [] for node in self.topology.G.nodes}
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
        that order, as YAFS does). Later calls continue the same simulation. Result files
        are flushed and closed at the end of each call (a later call appends).

        Args:
            until: the stop time; ``None`` runs until no event is left.
            show_progress_monitor: accepted for YAFS compatibility, unused.
            test_initial_deploy: only perform the initial allocation.
        """
        self.metrics.open()
        if not self._initialised:
            self._initialised = True
            for policy in self.population_policy.values():
                for app_name in policy["apps"]:
                    policy["population_policy"].initial_allocation(self, app_name)
            for policy in self.placement_policy.values():
                validate = getattr(policy["placement_policy"], "validate_apps", None)
                if validate is not None:
                    validate(self.apps)
                for app_name in policy["apps"]:
                    policy["placement_policy"].initial_allocation(self, app_name)
        self.until = until
        try:
            if not test_initial_deploy:
                self.env.run(until)
        finally:
            self.metrics.close()
