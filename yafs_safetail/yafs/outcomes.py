"""What happened to each copy of a redundantly dispatched request."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

CopyStatus = Literal["answered", "refused", "consumed", "lost"]


@dataclass(frozen=True, slots=True)
class CopyOutcome:
    """The fate of one copy (one of the N paths ``get_path`` returned for a request).

    Attributes:
        copy_index: position of the copy in the ``(paths, DES)`` lists, ``0..N-1``.
        dst_node: the node the copy was sent to (last node of its path).
        des: the process the copy was sent to.
        status: ``"answered"`` (the copy's lineage reached a sink), ``"refused"`` (a
            service model's ``admit`` said no), ``"consumed"`` (it ended at a module with
            no output), or ``"lost"`` (a message of the lineage could not be routed or
            reached a process that no longer exists).
        time_end: simulation time of the first sink arrival (answered) or of the moment
            the lineage ended (other statuses).
    """

    copy_index: int
    dst_node: Any
    des: Any
    status: CopyStatus
    time_end: float


@dataclass(frozen=True, slots=True)
class RequestOutcome:
    """A source-emitted request once every copy has settled.

    Attributes:
        request_id: the message ``id`` shared by every copy.
        app_name: the application.
        time_emit: when the source emitted it.
        copies: one :class:`CopyOutcome` per copy, in ``copy_index`` order.
        first: the answered copy with the smallest ``time_end`` (ties: lowest index), or
            ``None`` if no copy was answered.
        src_des: the source process that emitted the request.
        src_node: the node of that source when it emitted the request.
    """

    request_id: int
    app_name: Any
    time_emit: float
    copies: list[CopyOutcome]
    first: CopyOutcome | None
    src_des: Any = None
    src_node: Any = None

    @property
    def latency(self) -> float | None:
        """Time from emission to the first reply, or ``None`` if no copy was answered."""
        if self.first is None:
            return None
        return self.first.time_end - self.time_emit

    @property
    def refused(self) -> int:
        """Number of refused copies."""
        return sum(1 for c in self.copies if c.status == "refused")
