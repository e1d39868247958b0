"""Selection (routing + scheduling) policies: which replica serves a message and by which path."""

from __future__ import annotations

import logging
import random
from typing import TYPE_CHECKING, Any

import networkx as nx

if TYPE_CHECKING:
    from yafs_safetail.yafs.application import Message
    from yafs_safetail.yafs.core import Sim
    from yafs_safetail.yafs.outcomes import RequestOutcome

Paths = list[list[Any]]
DESList = list[Any]


class Selection:
    """Base class of YAFS selections; subclasses override :meth:`get_path`.

    ``get_path`` is called once per message sent and returns two parallel lists
    ``(paths, DES)``: ``paths[i]`` is a node list from the sender's node to the destination
    node (inclusive), ``DES[i]`` the destination process. Returning N paths sends N
    independent copies with the same request ``id`` (redundant dispatch); once every copy
    of a source-emitted request has settled the core calls :meth:`on_request_complete`.

    Subclasses need not call ``super().__init__()`` (YAFS examples don't).
    """

    logger = logging.getLogger(__name__)

    def __init__(self, logger: logging.Logger | None = None) -> None:
        if logger is not None:
            self.logger = logger
        # YAFS3's instance attributes (unused by the core, kept for scripts that read them).
        self.transmit = 0.0
        self.lat_acc = 0.0
        self.propagation = 0.0

    def get_path(
        self,
        sim: Sim,
        app_name: Any,
        message: Message,
        topology_src: Any,
        alloc_DES: dict[int, Any],  # noqa: N803 - YAFS name
        alloc_module: dict[Any, dict[str, list[int]]],
        traffic: dict[Any, float],
        from_des: int,
    ) -> tuple[Paths, DESList]:
        """Return ``(paths, DES)`` for ``message`` sent from node ``topology_src``.

        Args:
            sim: the simulation.
            app_name: the application.
            message: the message to route (``message.dst`` is the destination module).
            topology_src: the sender's node.
            alloc_DES: process id -> node.
            alloc_module: app -> module -> list of process ids.
            traffic: per-directed-link time until which the link is busy (YAFS link queues).
            from_des: the sending process id.

        The base class sends nothing (``([], [])``), as YAFS3's does.
        """
        self.logger.debug("Selection")
        return [], []

    def get_path_from_failure(
        self,
        sim: Sim,
        message: Message,
        link: tuple[Any, Any],
        alloc_DES: dict[int, Any],  # noqa: N803 - YAFS name
        alloc_module: dict[Any, dict[str, list[int]]],
        traffic: dict[Any, float],
        ctime: float,
        from_des: int,
    ) -> tuple[Paths, DESList]:
        """Re-route ``message`` whose next ``link`` no longer exists; default: drop it.

        Returning ``([], [])`` drops the message; otherwise the first path and DES are used,
        the path starting from the node where the message currently is.
        """
        return [], []

    def on_request_complete(self, sim: Sim, outcome: RequestOutcome) -> None:
        """Called once every copy of a request this selection dispatched has settled."""


class OneRandomPath(Selection):
    """One random simple path to each replica of the destination module (a copy to each).

    The path is drawn from ``networkx.all_simple_paths`` with Python's global ``random``
    (YAFS3's choice of generator). YAFS3's own class looks replicas up by
    ``message.app_name`` and ``alloc_module[des]``, which raises ``KeyError`` (so YAFS3
    drops the message); this one does what that class's docstring says.
    """

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        paths = []
        dst_des = []
        for des in alloc_module[app_name][message.dst]:
            candidates = list(nx.all_simple_paths(sim.topology.G, source=topology_src, target=alloc_DES[des]))
            if not candidates:
                continue
            paths.append(candidates[random.randint(0, len(candidates) - 1)])
            dst_des.append(des)
        return paths, dst_des


class First_ShortestPath(Selection):  # noqa: N801 - YAFS name
    """A shortest path to the *last* replica of the destination module (YAFS3's loop keeps
    the path of the last replica it visits; it also prints them, which this does not).

    ``networkx`` errors (no path, node not found) propagate, as in YAFS3.
    """

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        best_path: list[list[Any]] = []
        best_des: list[Any] = []
        for des in alloc_module[app_name][message.dst]:
            best_path = [list(nx.shortest_path(sim.topology.G, source=topology_src, target=alloc_DES[des]))]
            best_des = [des]
        return best_path, best_des
