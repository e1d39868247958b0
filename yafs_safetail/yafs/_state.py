"""The Sim state both engines read and write, declared once for the type checker.

``YAFS3Engine`` and ``DirectEngine`` are mixins of ``Sim``: ``Sim.__init__`` creates this state
and the engines' methods use it. The declarations below (annotations only, no values) tell
mypy what each attribute is; they change nothing at run time.
"""

from __future__ import annotations

import logging
import random
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np
    import simpy

    from yafs_safetail.yafs._records import _FloatTexts, _Lineage, _NetPut, _Request
    from yafs_safetail.yafs.application import Application, Message
    from yafs_safetail.yafs.metrics import Metrics
    from yafs_safetail.yafs.topology import Topology


class SimState:
    """Attributes of ``Sim`` used by its engine mixins (see ``core.Sim.__init__``)."""

    NODE_METRIC: str
    SINK_METRIC: str
    env: simpy.Environment
    topology: Topology
    logger: logging.Logger
    metrics: Metrics
    rng: np.random.Generator
    apps: dict[Any, Application]
    alloc_DES: dict[int, Any]  # noqa: N815 (YAFS's name)
    alloc_module: dict[Any, dict[str, list[int]]]
    selector_path: dict[Any, Any]
    des_process_running: dict[int, bool]
    last_busy_time: dict[tuple[Any, Any], float]
    request_listeners: list[Callable[..., None]]
    refused_copies: int
    lost_messages: int
    stop: bool
    # the event queue and its counter (simpy's own)
    _queue: list[Any]
    _eid: Any
    # results rows (None when results are not written)
    # Any: None when results are not written; the engines test one of the two, then use both
    _event_rows: Any
    _link_rows: Any
    _float_texts: _FloatTexts
    _flush_rows: int  # rows buffered before a flush
    # the delay and service hooks, bound once
    _hop_delay: Callable[..., float]
    _link_queues: bool
    _admit: Callable[..., bool]
    _service_time: Callable[..., float]
    _release: Callable[..., None]
    _concurrent: bool
    _py_random: random.Random | Any
    _py_random_given: bool
    # request lineages
    _complete: Callable[[_Request], None]
    _settle: Callable[[_Lineage], None]
    _lineage_message_done: Callable[[_Lineage], None]
    _message_lost: Callable[[Message], None]
    _new_message_id: Callable[[], int]
    _id_message: int
    # the direct engine
    _replicas: dict[Any, Any]  # by DES id (a message's idDES may still be None)
    _in_flight_hops: int
    _hop_end_callbacks: tuple[Callable[[Message], None]]
    _service_end_callbacks: tuple[Callable[[Any], None]]
    _source_tick_callbacks: tuple[Callable[[Any], None]]
    # the YAFS3 engine
    _net_items: deque[Message]
    _net_put_event: _NetPut
    _net_waiting: bool
    _pipes: dict[tuple[Any, Any, Any], Any]
    _pump: int
    _track_by_app: dict[Any, bool]
    _inline_fn: Any
    _inline_ev: Any
    _inline_eid: Any
    _y_inline_delay: bool
    _y_inline_service: bool
    _y_src_start_cbs: tuple[Callable[[Any], None]]
    _y_src_tick_cbs: tuple[Callable[[Any], None]]
    _y_net_put_cbs: tuple[Callable[[Any], None]]
    _y_net_get_cbs: tuple[Callable[[Any], None]]
    _y_hop_end_cbs: tuple[Callable[[Any], None]]
    _y_pipe_put_cbs: tuple[Callable[[Any], None]]
    _y_proc_start_cbs: tuple[Callable[[Any], None]]
    _y_proc_get_cbs: tuple[Callable[[Any], None]]
    _y_service_end_cbs: tuple[Callable[[Any], None]]
    _y_sink_end_cbs: tuple[Callable[[Any], None]]
