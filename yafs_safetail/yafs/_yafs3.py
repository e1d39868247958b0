"""The ``yafs3`` engine of :class:`~yafs_safetail.yafs.core.Sim`: YAFS3's event order, exactly.

YAFS3 runs one network process fed by a store, one process per hop transfer, and one process
per module replica or sink reading its own pipe. Rows are written by those processes, so the
*order* of rows written at one instant, the ``buffer`` column (hop transfers started and
not yet ended when a hop starts) and the moments at which selections and filters draw random
numbers all follow from the order in which simpy processes those events.

This engine keeps every event of YAFS3 that can change anything observable, in the same
order, and drops the rest: each store put is one event, each granted get is one event (the
message object itself is the event), each hop transfer and each service is one timeout (the
message again). The transfer process's own start event is folded into the network step
that creates it: simpy runs it right after that step, before any other event of that
instant, and all it does is count the transfer and start its timeout (pushed after the
network's next get, as in YAFS3). Sources and processes keep their start events (urgent), since
their first distribution draw and their place in the queue depend on them.

Nothing here is specific to any application; see ``docs/core.md`` for what is and is not
identical to YAFS3.
"""

from __future__ import annotations

import copy
import random
from heapq import heappush
from typing import Any

from simpy.events import NORMAL, URGENT

from yafs_safetail.yafs._records import _Lineage, _Proc, _Request, _Src, _Wake
from yafs_safetail.yafs._state import SimState
from yafs_safetail.yafs.application import Message
from yafs_safetail.yafs.selection import Selection

# YAFS compares the selection's DES list with these literals.
_NO_DES = [None]
_EMPTY_DES: list[list[Any]] = [[]]


_WAIT, _TRIG, _BUSY, _DONE = _Proc.WAIT, _Proc.TRIG, _Proc.BUSY, _Proc.DONE


def _copy_list(value: Any) -> Any:
    """``copy.copy`` of a message's list attribute (fast path for plain lists)."""
    return value.copy() if type(value) is list else copy.copy(value)


class YAFS3Engine(SimState):
    """Hot path of the ``yafs3`` engine (a mixin of ``Sim``; see the module docstring)."""

    # ----------------------------------------------------------------- deployment

    def _y_start_source(self, des: int, app_name: Any, message: Message, distribution: Any,
                        pure: bool) -> None:
        """Start a user (``pure``) or a module's source service: its process start event."""
        src = _Src(des, app_name, message, distribution, pure)
        src.callbacks = self._y_src_start_cbs
        heappush(self._queue, (self.env._now, URGENT, next(self._eid), src))

    def _y_start_process(self, des: int, app_name: Any, module: str,
                         registers: list[dict[str, Any]], is_sink: bool) -> None:
        """Create a module replica or sink with its pipe; its process starts urgently."""
        proc = _Proc(des, app_name, module, registers, is_sink)
        self._pipes[(app_name, module, des)] = proc
        heappush(self._queue, (self.env._now, URGENT, next(self._eid),
                               _Wake(self._y_proc_start_cbs, proc)))

    # ----------------------------------------------------------------- sources

    def _y_on_src_start(self, src: _Src) -> None:
        """The source process starts: first draw of its distribution, first wait."""
        if not self.stop and self.des_process_running[src.des]:
            self._y_wait_source(src)

    def _y_wait_source(self, src: _Src) -> None:
        delay = src.distribution.next()
        if delay < 0:
            raise ValueError(f"Negative delay {delay}")
        src.callbacks = self._y_src_tick_cbs
        heappush(self._queue, (self.env._now + delay, NORMAL, next(self._eid), src))

    def _y_on_src_tick(self, src: _Src) -> None:
        """A source wakes up: emits if still running, then waits again (YAFS's loop)."""
        rows = self._link_rows
        # Buffers are checked once per emission rather than once per row.
        if rows is not None and len(rows) + len(self._event_rows) >= self._flush_rows:
            self.metrics.flush()
            self._float_texts.clear()
        running = self.des_process_running
        des = src.des
        if running[des]:
            template = src.message
            cls = template.__class__
            msg = cls.__new__(cls)
            msg.__dict__ = template.__dict__.copy()
            now = self.env._now
            msg.timestamp = now
            app_name = src.app_name
            request = None
            if src.pure:
                # Only users' messages get an id; module sources keep the template's (-1).
                self._id_message = msg.id = self._id_message + 1
                wanted = self._track_by_app.get(app_name)
                if wanted is None:
                    wanted = self._tracked(app_name)
                if wanted or self.request_listeners:
                    request = _Request(msg.id, app_name, now, self.selector_path.get(app_name),
                                       des, self.alloc_DES.get(des))
            msg.original_DES_src = des
            self._y_send(app_name, msg, des, request, None, True)
        if not self.stop and running[des]:
            delay = src.distribution.next()
            if delay < 0:
                raise ValueError(f"Negative delay {delay}")
            src.callbacks = self._y_src_tick_cbs
            heappush(self._queue, (self.env._now + delay, NORMAL, next(self._eid), src))

    def _tracked(self, app_name: Any) -> bool:
        """Does the app's selection want request outcomes (overrides ``on_request_complete``)?

        The answer is kept per app (``_track_by_app``, reset by ``deploy_app``).
        """
        hook = getattr(self.selector_path.get(app_name).__class__, "on_request_complete", None)
        wanted = self._track_by_app[app_name] = hook is not None and hook is not Selection.on_request_complete
        return wanted

    # ----------------------------------------------------------------- sending

    def _y_send(self, app_name: Any, message: Message, des: int, request: _Request | None,
                lineage: _Lineage | None, stamp: bool = False) -> None:
        """YAFS's ``__send_message``: ask the selection, put one copy per path on the network.

        A ``KeyError`` anywhere (unknown app, process without a node, a selection's own
        lookup) means "unreachable", as in YAFS; copies already put stay in flight.
        """
        count = 0
        try:
            alloc = self.alloc_DES
            paths, des_dst = self.selector_path[app_name].get_path(
                self, app_name, message, alloc[des], alloc, self.alloc_module, self.last_busy_time,
                from_des=des,
            )
            if des_dst == _NO_DES or des_dst == _EMPTY_DES:
                self.logger.warning("(#DES:%s) unreachable destination for %s: path %s",
                                    des, message.name, paths)
            else:
                items = self._net_items
                cls = message.__class__
                state = message.__dict__
                for idx, path in enumerate(paths):
                    # Only the first copy's put event can wake the network: the others are
                    # processed right after it, when the network is already awake (or busy).
                    msg = cls.__new__(cls)
                    msg.__dict__ = state.copy()
                    msg.path = path.copy() if type(path) is list else copy.copy(path)
                    msg.app_name = app_name
                    msg.idDES = des_dst[idx]
                    if lineage is not None:
                        lineage.live += 1
                    elif stamp:
                        # A source's message: each copy knows its index and destination
                        # (messages derived from it inherit both).
                        msg.copy_index = idx
                        msg.copy_dst_node = path[-1]
                        if request is not None:
                            own = _Lineage(request, idx, path[-1], msg.idDES)
                            request.lineages.append(own)
                            own.live = 1
                            msg._lineage = own
                    items.append(msg)
                    if not count:
                        # The put's event: processed next if nothing else is due now.
                        queue = self._queue
                        now = self.env._now
                        if self._inline_fn is None and (not queue or queue[0][0] > now):
                            self._inline_fn = self._y_on_net_put
                            self._inline_ev = self._net_put_event
                            self._inline_eid = next(self._eid)
                        else:
                            heappush(queue, (now, NORMAL, next(self._eid), self._net_put_event))
                    count += 1
        except KeyError as exc:
            self.logger.warning("(#DES:%s) unreachable destination for %s: KeyError %s",
                                des, message.name, exc)
        if request is not None:
            request.unsettled = count
            if count == 0:
                self.lost_messages += 1
                self._complete(request)
        elif count == 0:
            self.lost_messages += 1
            if lineage is not None:
                lineage.lost = True

    # ----------------------------------------------------------------- the network process

    def _y_net_put(self) -> None:
        """A put on the network store: its event, processed next if nothing else is due now."""
        queue = self._queue
        now = self.env._now
        if self._inline_fn is None and (not queue or queue[0][0] > now):
            self._inline_fn = self._y_on_net_put
            self._inline_ev = self._net_put_event
            self._inline_eid = next(self._eid)
        else:
            heappush(queue, (now, NORMAL, next(self._eid), self._net_put_event))

    def _y_on_net_put(self, event: Any) -> None:
        """A put on the network store is processed: wake the network if it waits."""
        event.callbacks = self._y_net_put_cbs
        if self._net_waiting and self._net_items:
            self._net_waiting = False
            msg = self._net_items.popleft()
            queue = self._queue
            now = self.env._now
            if self._inline_fn is None and (not queue or queue[0][0] > now):
                # Its get is the next event: take the message now.
                self._y_on_net_get(msg)
            else:
                msg.callbacks = self._y_net_get_cbs
                heappush(queue, (now, NORMAL, next(self._eid), msg))

    def _y_on_net_get(self, msg: Message) -> None:
        """The network process takes ``msg``: deliver it, or start its next hop; then it
        loops (stops, takes the next message, or waits)."""
        path = msg.path
        dst_int = msg.dst_int
        if not path or path[-1] == dst_int or len(path) == 1:
            self._y_deliver(msg)
            return
        # YAFS locates the message by the node it is heading to, not by a hop counter;
        # -1 (or "") means it has not left its first node.
        kind = dst_int.__class__
        if kind is int:
            first_hop = dst_int < 0
        elif kind is str:
            first_hop = not dst_int
        else:
            first_hop = isinstance(dst_int, int) and dst_int < 0
        if first_hop:
            src = path[0]
            dst = path[1]
        else:
            src = dst_int
            dst = path[path.index(dst_int) + 1]
        msg.dst_int = dst
        now = self.env._now
        link = (src, dst)
        busy = self.last_busy_time
        last_used = busy.get(link, 0.0)
        transfer = None
        try:
            if self._y_inline_delay:
                edge = self.topology.G._adj[src][dst]
                latency = msg.bytes / (edge["BW"] * 1000000.0) + edge["PR"]
            else:
                latency = self._hop_delay(self, msg, src, dst)
            rows = self._link_rows
            if rows is not None:
                # A link's latency recurs on every hop over it: its text is made once.
                text = (self._float_texts[latency] if latency.__class__ is float and latency
                        else latency)
                start: Any = now  # a number, or its text when it is written again below
                if first_hop and now.__class__ is float and now and now == msg.timestamp:
                    # The emission time: written again as the message's time_emit.
                    start = msg._emit_text = repr(now)
                rows.append((msg.id, "LINK", src, dst, msg.app_name, text, msg.name, start,
                             msg.bytes, self._pump))
            if not self._link_queues:
                transfer = latency
            elif last_used < now:
                busy[link] = latency + now
                transfer = latency + 0.0
            else:
                shift = last_used - now
                busy[link] = now + shift + latency
                transfer = latency + shift
        except Exception:  # noqa: BLE001 - YAFS: any failure of the hop means the link is gone
            self._y_link_failed(msg, link, now)
        queue = self._queue
        items = self._net_items
        if self.stop:
            self._net_alive = False
        elif items:
            nxt = items.popleft()
            nxt.callbacks = self._y_net_get_cbs
            heappush(queue, (now, NORMAL, next(self._eid), nxt))
        else:
            self._net_waiting = True
        if transfer is not None:
            # The transfer process starts (urgent: before anything else at this instant).
            self._pump += 1
            msg.callbacks = self._y_hop_end_cbs
            heappush(queue, (now + transfer, NORMAL, next(self._eid), msg))

    def _y_deliver(self, msg: Message) -> None:
        """The network puts ``msg`` in its process's pipe, then loops."""
        now = self.env._now
        msg.timestamp_rec = now
        proc = self._pipes[(msg.app_name, msg.dst, msg.idDES)]
        msg._at = proc
        proc.items.append(msg)
        proc.callbacks = self._y_pipe_put_cbs
        queue = self._queue
        items = self._net_items
        if items and not self.stop:
            # The pipe's put event, then the network's next get (in that order).
            heappush(queue, (now, NORMAL, next(self._eid), proc))
            nxt = items.popleft()
            nxt.callbacks = self._y_net_get_cbs
            heappush(queue, (now, NORMAL, next(self._eid), nxt))
            return
        if self.stop:
            self._net_alive = False
        else:
            self._net_waiting = True
        if self._inline_fn is None and (not queue or queue[0][0] > now):
            # The pipe's put event is next; a waiting process then takes the message at
            # once (its get is next in turn); a busy one leaves it in the pipe.
            if proc.state == _WAIT:
                proc.state = _TRIG
                proc.items.popleft()
                self._y_on_proc_get(msg)
        else:
            heappush(queue, (now, NORMAL, next(self._eid), proc))

    def _y_on_hop_end(self, msg: Message) -> None:
        """A hop transfer ends: the message goes back into the network store."""
        self._pump -= 1
        queue = self._queue
        if self._net_waiting and self._inline_fn is None and (not queue or queue[0][0] > self.env._now):
            # The put's event is next and wakes the waiting network (its store was empty),
            # whose get is next in turn: it takes the message now.
            self._net_waiting = False
            self._y_on_net_get(msg)
            return
        self._net_items.append(msg)
        if self._inline_fn is None and (not queue or queue[0][0] > self.env._now):
            return  # the put's event is next and finds the network busy: nothing to do
        heappush(queue, (self.env._now, NORMAL, next(self._eid), self._net_put_event))

    def _y_link_failed(self, msg: Message, link: tuple[Any, Any], now: float) -> None:
        """The hop's link is gone: YAFS asks ``get_path_from_failure`` and re-queues the
        message with the path it returns (the selection may move ``msg.dst_int``)."""
        self.logger.warning("link %s unreachable at %s; re-routing %s", link, now, msg.name)
        paths, des_dst = self.selector_path[msg.app_name].get_path_from_failure(
            self, msg, link, self.alloc_DES, self.alloc_module, self.last_busy_time, now,
            from_des=msg.idDES,
        )
        if des_dst == [] and paths == []:
            self._message_lost(msg)
            return
        first = paths[0]
        msg.path = first.copy() if type(first) is list else copy.copy(first)
        msg.idDES = des_dst[0]
        self._net_items.append(msg)
        heappush(self._queue, (self.env._now, NORMAL, next(self._eid), self._net_put_event))

    # ----------------------------------------------------------------- modules and sinks

    def _y_on_proc_start(self, event: _Wake) -> None:
        self._y_proc_next(event.item)

    def _y_proc_next(self, proc: _Proc) -> None:
        """Top of YAFS's consumer loop: go on while running, take the next message or wait."""
        if not self.stop and self.des_process_running[proc.des]:
            if proc.items:
                proc.state = _TRIG
                self._y_grant(proc.items.popleft())
            else:
                proc.state = _WAIT
        else:
            proc.state = _DONE

    def _y_grant(self, msg: Message) -> None:
        """A process's get is granted: ``msg`` is its event, processed next if nothing else
        is due now."""
        queue = self._queue
        now = self.env._now
        if self._inline_fn is None and (not queue or queue[0][0] > now):
            self._inline_fn = self._y_on_proc_get
            self._inline_ev = msg
            self._inline_eid = next(self._eid)
        else:
            msg.callbacks = self._y_proc_get_cbs
            heappush(queue, (now, NORMAL, next(self._eid), msg))

    def _y_on_pipe_put(self, proc: _Proc) -> None:
        """A put on a process's pipe is processed: hand the message over if it waits."""
        proc.callbacks = self._y_pipe_put_cbs
        if proc.state == _WAIT and proc.items:
            proc.state = _TRIG
            self._y_grant(proc.items.popleft())

    def _y_on_proc_get(self, msg: Message) -> None:
        """The process takes ``msg``: record it and serve it (sinks serve in zero time)."""
        proc = msg._at
        now = self.env._now
        if proc.is_sink:
            service = self._y_record(proc, msg, self.SINK_METRIC, now)
            lineage = msg._lineage
            if lineage is not None:
                if lineage.status is None:
                    lineage.status = "answered"
                    lineage.time_end = now
                    self._settle(lineage)
                self._lineage_message_done(lineage)
            callbacks = self._y_sink_end_cbs
        else:
            if msg.name not in proc.by_name:
                # No transmission consumes it: YAFS's loop goes straight back to its pipe.
                self._message_lost(msg)
                self._y_proc_next(proc)
                return
            if not self._y_inline_service:
                node = self.alloc_DES.get(proc.des)
                if not self._admit(self, msg, proc.des, node, proc.module):
                    self.refused_copies += 1
                    lineage = msg._lineage
                    if lineage is not None:
                        lineage.refused = True
                        self._lineage_message_done(lineage)
                    self._y_proc_next(proc)
                    return
            service = self._y_record(proc, msg, self.NODE_METRIC, now)
            callbacks = self._y_service_end_cbs
        if service < 0:
            raise ValueError(f"Negative delay {service}")
        proc.state = _BUSY
        queue = self._queue
        when = now + service
        if (when == now and when.__class__ is now.__class__ and self._inline_fn is None
                and (not queue or queue[0][0] > now)):
            # A zero service (sinks) ends at this very instant: its end is the next event.
            # (A float zero turns an integer clock into a float one, so that stays queued.)
            self._inline_fn = callbacks[0]
            self._inline_ev = msg
            self._inline_eid = next(self._eid)
        else:
            msg.callbacks = callbacks
            heappush(queue, (when, NORMAL, next(self._eid), msg))

    def _y_record(self, proc: _Proc, msg: Message, kind: str, now: float) -> float:
        """YAFS's ``__update_node_metrics``: the service time, and the row.

        Sink-ness is YAFS's test ``module in app.get_sink_modules()`` (a substring test when
        that returns a string). A process whose node or app is gone (``KeyError``) writes no
        row and takes 1 time unit, as in YAFS.
        """
        app_name = proc.app_name
        des = proc.des
        try:
            alloc = self.alloc_DES
            if proc.module in self.apps[app_name].get_sink_modules():
                id_node = alloc[des]
                service: Any = 0  # YAFS writes a sink's zero service as the integer 0
            else:
                id_node = alloc[des]
                if self._y_inline_service:
                    service = msg.inst / float(self.topology.G._node[id_node]["IPT"])
                else:
                    service = self._service_time(self, msg, des, id_node, proc.module)
            # YAFS: the last replica of the sending module on the path's first node; any
            # failure of that lookup (e.g. the sender is a user, not a module) falls back to
            # the message's original source process.
            modules = self.alloc_module.get(app_name)
            senders = modules.get(msg.src) if type(modules) is dict else None
            if senders is None:
                source_des = msg.original_DES_src
            else:
                try:
                    source_des = -1
                    if senders:
                        first = msg.path[0]
                        nodes = list(map(alloc.__getitem__, senders))
                        if first in nodes:
                            source_des = senders[len(nodes) - 1 - nodes[::-1].index(first)]
                except Exception:  # noqa: BLE001 - YAFS's bare except
                    source_des = msg.original_DES_src
            rows = self._event_rows
            if rows is not None:
                # Texts made once: a service time (it recurs), and the arrival time when it
                # is also the start time (no wait in the pipe).
                service_text = (self._float_texts[service] if service.__class__ is float and service
                                else service)
                reception: Any = float(msg.timestamp_rec)  # a number, or its text
                start: Any
                if reception == now and now.__class__ is float and now:
                    reception = start = repr(now)
                else:
                    start = now
                emitted = float(msg.timestamp)
                if emitted.__class__ is float and emitted:
                    emitted = msg.__dict__.get("_emit_text", emitted)
                rows.append((msg.id, kind, app_name, proc.module, msg.name, source_des, des,
                             msg.path[0], id_node, msg.src, service_text, start, service + now,
                             emitted, reception))
            return service
        except KeyError:
            self.logger.critical("process %s (%s) has no node or its node lost its attributes; "
                                 "no row, service time 1", des, proc.module)
            return 1

    def _y_on_sink_end(self, msg: Message) -> None:
        self._y_proc_next(msg._at)

    def _y_on_service_end(self, msg: Message) -> None:
        """A service ends: send what each matching transmission emits, then loop."""
        proc = msg._at
        des = proc.des
        if not self._y_inline_service:
            self._release(self, msg, des, self.alloc_DES.get(des), proc.module)
        lineage = msg._lineage
        app_name = proc.app_name
        for out, dist, param, destinations, probabilities in proc.by_name[msg.name]:
            if not out:
                continue
            if dist and not self._y_accepts(dist, param):
                continue
            if not destinations:
                derived = out.clone()
                derived.timestamp = self.env._now
                derived.id = msg.id
                derived.last_idDes = _copy_list(msg.last_idDes)
                derived.last_idDes.append(des)
                derived.copy_index = msg.copy_index
                derived.copy_dst_node = msg.copy_dst_node
                if lineage is not None:
                    derived._lineage = lineage
                self._y_send(app_name, derived, des, None, lineage)
                continue
            # Broadcast to listed modules: YAFS3 itself fails here (its registers lack "p");
            # this sends one message to each listed module with probability p[i].
            draw = self._py_random.random
            for index, module_dst in enumerate(destinations):
                if draw() <= probabilities[index]:
                    derived = out.clone()
                    derived.timestamp = self.env._now
                    derived.id = msg.id
                    derived.dst = module_dst
                    derived.last_idDes = _copy_list(msg.last_idDes)
                    derived.last_idDes.append(des)
                    derived.copy_index = msg.copy_index
                    derived.copy_dst_node = msg.copy_dst_node
                    if lineage is not None:
                        derived._lineage = lineage
                    self._y_send(app_name, derived, des, None, lineage)
        if lineage is not None:
            self._lineage_message_done(lineage)
        self._y_proc_next(proc)

    def _y_accepts(self, dist: Any, param: dict[str, Any]) -> bool:
        """Call a forwarding filter as YAFS does; a seeded ``py_random`` is passed to filters
        that take one (``fractional_selectivity``)."""
        if self._py_random_given and getattr(dist, "wants_rng", False) and "rng" not in param:
            return bool(dist(rng=self._py_random, **param))
        return bool(dist(**param))


# The global ``random`` module stands for "Python's global generator" (YAFS's draws).
GLOBAL_RANDOM = random
