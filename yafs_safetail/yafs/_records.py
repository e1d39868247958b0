"""Small records shared by the two engines of :class:`~yafs_safetail.yafs.core.Sim`.

Each is a ``__slots__`` class: one of them is created per request, copy or process, so they
stay small. The ones that sit on simpy's heap as events (``_Wake``, ``_Src``, ``_Proc``,
``_NetPut``) carry only what simpy's ``step`` reads: ``callbacks`` and ``_ok``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from yafs_safetail.yafs.application import Message
    from yafs_safetail.yafs.distribution import Distribution


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



class _Src:
    """A source of the YAFS3 engine: a user (pure source) or a module's source service.

    The object itself is the simpy event of the source's next wake-up (its process start,
    then each emission), so a source costs no allocation per tick.
    """

    __slots__ = ("des", "app_name", "message", "distribution", "pure", "callbacks")
    _ok = True

    def __init__(self, des: int, app_name: Any, message: Message, distribution: Distribution,
                 pure: bool) -> None:
        self.des = des
        self.app_name = app_name
        self.message = message
        self.distribution = distribution
        self.pure = pure
        self.callbacks: Any = None


class _Proc:
    """A module replica or sink of the YAFS3 engine: one process with its message pipe.

    ``state`` follows YAFS's consumer process: ``INIT`` until the process starts, ``WAIT``
    while it waits on an empty pipe, ``TRIG`` once its get has been granted (the message is
    on the heap), ``BUSY`` during a service, ``DONE`` after its loop ended. The object is
    also the pipe's put event (``callbacks``), pushed once per put as simpy does.

    ``by_name`` maps each consumed message name to its transmission rules in registration
    order: ``(message_out, dist, param, module_dest, p)``.
    """

    __slots__ = ("des", "app_name", "module", "by_name", "is_sink", "items", "state", "callbacks")
    _ok = True

    INIT, WAIT, TRIG, BUSY, DONE = range(5)

    def __init__(self, des: int, app_name: Any, module: str, registers: list[dict[str, Any]],
                 is_sink: bool) -> None:
        self.des = des
        self.app_name = app_name
        self.module = module
        self.by_name: dict[str, list[tuple[Any, Any, dict[str, Any], list[str], list[float]]]] = {}
        for register in registers:
            self.by_name.setdefault(register["message_in"].name, []).append((
                register["message_out"], register["dist"], register.get("param", {}),
                register.get("module_dest") or [], register.get("p") or [],
            ))
        self.is_sink = is_sink
        self.items: deque[Message] = deque()
        self.state = _Proc.INIT
        self.callbacks: Any = None


class _NetPut:
    """The put event of YAFS's network store (one object, pushed once per put)."""

    __slots__ = ("callbacks",)
    _ok = True

    def __init__(self, callbacks: tuple[Callable[[Any], None]]) -> None:
        self.callbacks = callbacks


class _Inline:
    """An event that was to run next but goes back into the queue: calls ``fn(event)``."""

    __slots__ = ("callbacks", "event", "fn")
    _ok = True

    def __init__(self, fn: Callable[[Any], None], event: Any) -> None:
        self.callbacks = (self._fire,)
        self.event = event
        self.fn = fn

    def _fire(self, _: Any) -> None:
        self.fn(self.event)


class _FloatTexts(dict[float, str]):
    """The text of each float written to the yafs3 engine's rows since the last flush.

    A link's latency and a service time recur on every hop and copy, and writing a float is
    the costliest part of a row, so its text is made once, here, on the first miss. The
    engine reads it inline (``texts[value]``): a subscript that hits stays in C, where a
    helper method would add a Python call to every row.
    """

    __slots__ = ()

    def __missing__(self, value: float) -> str:
        text = self[value] = repr(value)
        return text


class _StopRun(Exception):
    """Raised by the ``until`` event to leave the event loop (simpy's StopSimulation)."""


class _Until:
    """The event at ``until`` that ends :meth:`Sim.run` (urgent, as simpy schedules it)."""

    __slots__ = ("callbacks",)
    _ok = True

    def __init__(self) -> None:
        self.callbacks = (_until_reached,)


def _until_reached(event: Any) -> None:
    raise _StopRun
