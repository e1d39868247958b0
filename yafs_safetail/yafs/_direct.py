"""The ``direct`` engine of :class:`~yafs_safetail.yafs.core.Sim`: one event per hop end,
service end and source tick, no network process.

This is the engine for custom delay models (``Sim(..., link_delay=..., service_model=...)``,
as the SafeTail edge model uses): every hop starts the moment the previous one ends, so a
message's times are YAFS's but the order of rows written at the same instant can differ
from YAFS3's, whose network process and module pipes add zero-delay events between hops.
``docs/core.md`` lists what else differs from the ``yafs3`` engine.
"""

from __future__ import annotations

from collections.abc import Callable
from heapq import heappush
from typing import Any

from simpy.events import NORMAL

from yafs_safetail.yafs._records import _Lineage, _Replica, _Request, _Source, _Wake
from yafs_safetail.yafs._state import SimState
from yafs_safetail.yafs.application import Message


class DirectEngine(SimState):
    """Hot path of the ``direct`` engine (a mixin of ``Sim``; see the module docstring)."""

    # ----------------------------------------------------------------- deployment

    def _d_start_source(self, des: int, app_name: Any, message: Message, distribution: Any,
                        pure: bool) -> None:
        """Start a user or a module's source service (every emission gets a request id)."""
        self._schedule_source(_Source(des, app_name, message, distribution))

    def _d_start_process(self, des: int, app_name: Any, module: str,
                         registers: list[dict[str, Any]], is_sink: bool) -> None:
        """Register a module replica or a sink."""
        self._replicas[des] = _Replica(des, app_name, module, registers, is_sink=is_sink)

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
            self._message_lost(msg)
            return
        msg.path = new_path
        msg.idDES = des_list[0]
        msg._hop = new_path.index(src)
        self._forward(msg)

    # ----------------------------------------------------------------- modules and sinks

    def _deliver(self, msg: Message) -> None:
        """``msg`` reached its destination node: hand it to its process."""
        now = self.env._now
        msg.timestamp_rec = now
        replica = self._replicas.get(msg.idDES)
        if replica is None or not self.des_process_running.get(replica.des, False):
            self._message_lost(msg)
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
            self._message_lost(msg)
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


    def _schedule_source(self, source: _Source) -> None:
        # _Wake is a duck-typed simpy event (callbacks, _ok, _value), cheaper than simpy.Event.
        self.env.schedule(_Wake(self._source_tick_callbacks, source), NORMAL,  # type: ignore[arg-type]
                          source.distribution.next())

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

