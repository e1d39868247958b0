"""Applications (DAGs of modules exchanging messages) and the messages themselves."""

from __future__ import annotations

import os
import random
from collections.abc import Callable
from typing import Any

from yafs_safetail.yafs.errors import (
    YAFSInputError,
    read_json_input,
    require_id,
    require_key,
    require_list,
    require_mapping,
    require_number,
)


class Message:
    """A message between two modules of an application (YAFS's ``Message``).

    YAFS fields: ``name``, ``src``/``dst`` (module names), ``inst`` (instructions),
    ``bytes``, ``broadcasting``; set by the core: ``timestamp`` (emission time),
    ``timestamp_rec`` (arrival at the destination node), ``path`` (node list),
    ``dst_int`` (next node on the path), ``app_name``, ``idDES`` (destination process),
    ``id`` (request id shared by every copy and derived message), ``original_DES_src``
    (the source process that emitted the request), ``last_idDes`` (module processes the
    lineage went through).

    Per-copy fields for the delay hooks (set by the core on every copy and inherited by the
    messages derived from it):

    * ``copy_index``: index ``0..N-1`` of the copy among the ``N`` paths that
      ``Selection.get_path`` returned for the source-emitted request.
    * ``copy_dst_node``: the topology node that copy was sent to (e.g. the edge server);
      a reply derived from the copy keeps the same value.

    The class keeps a ``__dict__`` (not ``__slots__``) because YAFS scripts attach their
    own attributes to messages; copies are made with :meth:`clone`, a shallow dict copy.
    While a message crosses a link the core schedules the message itself as the simpy event
    of the hop's end (saving one object per hop), hence ``_ok`` and ``callbacks``.
    """

    _ok = True
    callbacks: Any = None
    # Set by the engines while the message is in flight (see the class docstring).
    _hop: Any
    _at: Any
    _emit_text: str

    def __init__(
        self,
        name: str,
        src: str,
        dst: str,
        instructions: float = 0,
        bytes: float = 0,  # noqa: A002 - YAFS keyword name
        broadcasting: bool = False,
    ) -> None:
        self.name = name
        self.src = src
        self.dst = dst
        self.inst = instructions
        self.bytes = bytes
        self.broadcasting = broadcasting
        self.timestamp: float = 0
        self.timestamp_rec: float = 0
        self.path: list[Any] = []
        self.dst_int: Any = -1
        self.app_name: str | None = None
        self.idDES: int | None = None
        self.last_idDes: list[int] = []
        self.id: int = -1
        self.original_DES_src: int | None = None
        self.copy_index: int = -1
        self.copy_dst_node: Any = None
        # Core-private: the copy lineage record.
        self._lineage: Any = None

    @property
    def instructions(self) -> float:
        """The number of instructions (YAFS stores it as ``inst``)."""
        return self.inst

    def clone(self) -> Message:
        """Return a shallow copy (lists such as ``path`` are shared until reassigned)."""
        cls = self.__class__
        new = cls.__new__(cls)
        new.__dict__ = self.__dict__.copy()
        return new

    def __repr__(self) -> str:
        return f"Message({self.name!r}, {self.src!r} -> {self.dst!r}, id={self.id})"


def fractional_selectivity(threshold: float, rng: Any = None) -> bool:
    """Return True with probability ``threshold`` (YAFS's forwarding filter).

    Draws one number ``u`` in [0, 1) and returns ``u <= threshold``. As in YAFS the draw
    happens even when the threshold is 1, so the stream of draws does not depend on the
    thresholds. ``rng=None`` draws from Python's global ``random`` (YAFS-compatible); pass
    any generator with a ``random()`` method (a ``random.Random``, a
    ``numpy.random.Generator``) to draw from it instead: the core passes ``Sim(py_random=)``
    (``yafs3`` engine) or ``sim.rng`` (``direct`` engine).
    """
    draw = random.random() if rng is None else rng.random()
    return bool(draw <= threshold)


# The core passes its own generator as ``rng`` to forwarding filters carrying this flag.
fractional_selectivity.wants_rng = True  # type: ignore[attr-defined]


class Application:
    """An application: modules, the messages between them, and how each module reacts.

    Attributes:
        name: unique application name (YAFS allows ints, as in its tutorial 01).
        services: module name -> list of service registers (dicts with ``type``,
            ``message_in``, ``message_out``, ``dist``, ``param``, ``module_dest``, ``p``).
        messages: source messages (those emitted by users), by name.
    """

    TYPE_SOURCE = "SOURCE"
    TYPE_MODULE = "MODULE"
    TYPE_SINK = "SINK"

    def __init__(self, name: Any) -> None:
        self.name = name
        self.services: dict[str, list[dict[str, Any]]] = {}
        self.messages: dict[str, Message] = {}
        self.modules: list[str] = []
        self.modules_src: list[str] = []
        # YAFS: the *name* of the last sink declared (a string), or [] when there is none.
        self.modules_sink: Any = []
        self.data: list[dict[str, Any]] = []
        self.all_messages: dict[str, Message] = {}
        self._sinks: list[str] = []

    def __str__(self) -> str:
        lines = [f"App {self.name!r}: modules {self.modules}"]
        for module, services in self.services.items():
            for service in services:
                if service["type"] == self.TYPE_SOURCE:
                    lines.append(f"  {module}: emits {service['message_out'].name}")
                else:
                    out = service["message_out"]
                    lines.append(f"  {module}: {service['message_in'].name} -> "
                                 f"{out.name if isinstance(out, Message) else '(nothing)'}")
        return "\n".join(lines)

    def set_modules(self, data: list[dict[str, dict[str, Any]]]) -> None:
        """Declare modules: ``[{name: {"Type": TYPE_*, "RAM": ...}}, ...]``."""
        for module in data:
            ((name, spec),) = module.items()
            kind = spec.get("Type", self.TYPE_MODULE)
            if kind == self.TYPE_SOURCE:
                self.modules_src.append(name)
            elif kind == self.TYPE_SINK:
                self.modules_sink = name
                self._sinks.append(name)
            self.modules.append(name)
        self.data = data

    def get_pure_modules(self) -> list[str]:
        """Modules that are neither pure sources nor sinks (YAFS's test, so with a single
        sink name a module whose name is a substring of it counts as a sink)."""
        return [m for m in self.modules if m not in self.modules_src and m not in self.modules_sink]

    def get_sink_modules(self) -> Any:
        """YAFS3's value: the name of the *last* sink module declared (a string), or ``[]``
        if there is none. :meth:`sink_module_list` gives every sink."""
        return self.modules_sink

    def sink_module_list(self) -> list[str]:
        """Every sink (actuator) module declared, in order."""
        return list(self._sinks)

    def add_source_messages(self, msg: Message) -> None:
        """Register a message emitted by pure sources (users), controlled by populations."""
        self.messages[msg.name] = msg
        self.all_messages[msg.name] = msg

    def get_message(self, name: str) -> Message:
        """Return the source message called ``name``."""
        return self.messages[name]

    def add_service_source(
        self,
        module_name: str,
        distribution: Any = None,
        message: Message | None = None,
        module_dest: list[str] | None = None,
        p: list[float] | None = None,
    ) -> None:
        """Make a (non-pure) module emit ``message`` periodically, following ``distribution``."""
        if distribution is None:
            return
        self.services.setdefault(module_name, []).append(
            {
                "type": self.TYPE_SOURCE,
                "dist": distribution,
                "message_out": message,
                "module_dest": module_dest or [],
                "p": p or [],
            }
        )

    def add_service_module(
        self,
        module_name: str,
        message_in: Message,
        message_out: Message | str = "",
        distribution: Callable[..., bool] | str = "",
        module_dest: list[str] | None = None,
        p: list[float] | None = None,
        **param: Any,
    ) -> None:
        """Make ``module_name`` consume ``message_in`` and (optionally) emit ``message_out``.

        Args:
            module_name: the module.
            message_in: the message it consumes.
            message_out: the message it emits after service; empty = consume only.
            distribution: a forwarding filter called as ``distribution(**param)`` (e.g.
                :func:`fractional_selectivity`); empty = always forward.
            module_dest: broadcast destinations (one send per entry, each with probability
                ``p[i]``).
            p: broadcast probabilities.
            **param: arguments of ``distribution``.
        """
        self.services.setdefault(module_name, []).append(
            {
                "type": self.TYPE_MODULE,
                "dist": distribution,
                "param": param,
                "message_in": message_in,
                "message_out": message_out,
                "module_dest": module_dest or [],
                "p": p or [],
            }
        )
        for msg in (message_in, message_out):
            if isinstance(msg, Message):
                self.all_messages.setdefault(msg.name, msg)


def create_applications_from_json(
    data: list[dict[str, Any]] | str | os.PathLike[str],
) -> dict[Any, Application]:
    """Build ``{name: Application}`` from a YAFS application JSON (list, or path to it).

    Raises:
        YAFSInputError: not JSON, missing/mistyped keys, negative bytes/instructions, or a
            message/transmission naming a module or message that does not exist.
    """
    data, source = read_json_input(data, "application")
    if not isinstance(data, list):
        raise YAFSInputError(source, "", "", f"expected a list of applications, got {type(data).__name__}")
    applications: dict[Any, Application] = {}
    for app_index, raw_app in enumerate(data):
        app_entry = f"app[{app_index}]"
        spec = require_mapping(raw_app, source, app_entry)
        name = require_id(spec, "name", source, app_entry)
        app_entry = f"app {name!r}"
        app = Application(name=name)

        module_names: list[str] = []
        modules: list[dict[str, dict[str, Any]]] = [{"None": {"Type": Application.TYPE_SOURCE}}]
        for index, raw in enumerate(require_list(spec, "module", source, app_entry)):
            entry = f"{app_entry} module[{index}]"
            module = require_mapping(raw, source, entry)
            module_name = require_id(module, "name", source, entry)
            ram = require_number(module, "RAM", source, entry, required=False)
            module_names.append(module_name)
            modules.append({module_name: {"RAM": ram, "Type": Application.TYPE_MODULE}})
        app.set_modules(modules)

        messages: dict[str, Message] = {}
        for index, raw in enumerate(require_list(spec, "message", source, app_entry)):
            entry = f"{app_entry} message[{index}]"
            message = require_mapping(raw, source, entry)
            msg_name = require_id(message, "name", source, entry)
            src = require_id(message, "s", source, entry)
            dst = require_id(message, "d", source, entry)
            size = require_number(message, "bytes", source, entry)
            instructions = require_number(message, "instructions", source, entry)
            for key, module_name in (("s", src), ("d", dst)):
                if module_name != "None" and module_name not in module_names:
                    raise YAFSInputError(
                        source, entry, key, f"names module {module_name!r}, which is not in 'module'"
                    )
            messages[msg_name] = Message(msg_name, src, dst, instructions=instructions, bytes=size)
            if src == "None":
                app.add_source_messages(messages[msg_name])

        for index, raw in enumerate(require_list(spec, "transmission", source, app_entry)):
            entry = f"{app_entry} transmission[{index}]"
            transmission = require_mapping(raw, source, entry)
            module_name = require_key(transmission, "module", source, entry)
            if module_name not in module_names:
                raise YAFSInputError(
                    source, entry, "module", f"names module {module_name!r}, which is not in 'module'"
                )
            linked = []
            for key in ("message_in", "message_out"):
                if key == "message_out" and key not in transmission:
                    continue
                msg_name = require_key(transmission, key, source, entry)
                if msg_name not in messages:
                    raise YAFSInputError(
                        source, entry, key, f"names message {msg_name!r}, which is not in 'message'"
                    )
                linked.append(messages[msg_name])
            if len(linked) == 2:
                app.add_service_module(
                    module_name, linked[0], linked[1], fractional_selectivity, threshold=1.0
                )
            else:
                app.add_service_module(module_name, linked[0])
        applications[name] = app
    return applications
