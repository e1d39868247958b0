"""The two pluggable delay models of the core, and YAFS's defaults.

The core asks a :class:`LinkDelay` for every hop and a :class:`ServiceModel` for every
message reaching a module replica. Set them with ``Sim(..., link_delay=...,
service_model=...)`` or ``sim.set_link_delay(...)`` / ``sim.set_service_model(...)``.

Per-copy information for the models is on the message: ``message.copy_index`` (which of the
N copies of the request this lineage is) and ``message.copy_dst_node`` (the node that copy was
dispatched to); ``message.id`` is the request id and ``message.path`` the node path.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    from yafs_safetail.yafs.application import Message
    from yafs_safetail.yafs.core import Sim


@runtime_checkable
class LinkDelay(Protocol):
    """Delay of one hop of one message.

    Attributes:
        uses_link_queues: True applies YAFS's per-direction FIFO link queues on top of
            :meth:`hop_delay_s` (a message waits until the link is free, then occupies it
            for its whole hop delay); False lets every hop start at once.
    """

    uses_link_queues: bool

    def hop_delay_s(self, sim: Sim, message: Message, src_node: Any, dst_node: Any) -> float:
        """Return the hop delay (simulation time units) of ``message`` from ``src_node`` to
        ``dst_node``; raise ``KeyError`` if the link does not exist (the core then asks the
        selection's ``get_path_from_failure``)."""
        ...


@runtime_checkable
class ServiceModel(Protocol):
    """Admission and service time of a message at a module replica.

    Attributes:
        concurrent: False = YAFS: one FIFO queue per replica, one message in service at a
            time. True = every admitted message is served at once, in parallel (no queue);
            :meth:`release` is called when its service ends.
    """

    concurrent: bool

    def admit(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> bool:
        """Called when ``message`` reaches replica ``des``; False refuses it (no result row,
        the copy is recorded as refused)."""
        ...

    def service_time_s(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> float:
        """Called when the service of ``message`` starts; returns its duration."""
        ...

    def release(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> None:
        """Called when the service of ``message`` ends."""
        ...


class YAFSLinkDelay:
    """YAFS's hop delay: ``bytes / (BW * 1e6) + PR`` with per-direction link queues.

    Units are YAFS's: ``BW`` in "mega-bytes per time unit" (there is no factor 8: a message
    of ``B`` bytes over ``BW = 1`` takes ``B / 1e6`` time units to transmit) and ``PR`` in
    time units. The edge attributes are read at every hop, so changing ``G`` during a run
    takes effect immediately.
    """

    uses_link_queues = True

    def hop_delay_s(self, sim: Sim, message: Message, src_node: Any, dst_node: Any) -> float:
        edge = sim.topology.G._adj[src_node][dst_node]
        return message.bytes / (edge["BW"] * 1000000.0) + edge["PR"]


class YAFSServiceModel:
    """YAFS's service: ``instructions / IPT`` of the node, FIFO per replica, admits all."""

    concurrent = False

    def admit(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> bool:
        return True

    def service_time_s(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> float:
        return message.inst / float(sim.topology.G._node[node]["IPT"])

    def release(self, sim: Sim, message: Message, des: int, node: Any, module: str) -> None:
        return None
