"""What one request achieved under one method: the one record type from the simulation to the
``requests.csv`` row.

The simulation (``sim.selection``) builds a :class:`RequestRecord` when a request completes, the
method's policy sees it as its feedback (``methods.Policy.feedback``), and
:func:`records_frame` turns a phase's records into the rows of ``requests.csv`` (schema
:data:`REQUESTS_SCHEMA`, docs/results.md), without any other intermediate form.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import pandas as pd

if TYPE_CHECKING:
    from yafs_safetail.edge.movement import Movement

PHASES: tuple[str, ...] = ("train", "test")

# requests.csv, in file order. Kinds: "str", "int" (never missing), "float" (may be NaN).
REQUESTS_SCHEMA: dict[str, str] = {
    "method": "str",
    "phase": "str",
    "episode": "int",
    "step": "int",
    "request_id": "int",
    "latency_s": "float",
    "target_s": "float",
    "deviation_s": "float",
    "n_selected": "int",
    "access_rate": "float",
    "servers": "str",
    "reward": "float",
    "refused": "int",
    "fallback": "int",
    "upload_s": "float",
    "propagation_s": "float",
    "download_s": "float",
    "compute_s": "float",
}
REQUESTS_COLUMNS: tuple[str, ...] = tuple(REQUESTS_SCHEMA)
#: Columns written after ``epsilon`` (why each request ended and what its copies cost,
#: docs/failures_energy.md), in file order: added after the first release, so the columns
#: before them keep their places and bytes, and a requests.csv written before them still reads.
OUTCOME_ENERGY_SCHEMA: dict[str, str] = {
    "end_reason": "str",
    "lost": "int",
    "energy_j": "float",
    "server_energy_j": "float",
    "radio_energy_j": "float",
    "saved_energy_j": "float",
}
OUTCOME_ENERGY_COLUMNS: tuple[str, ...] = tuple(OUTCOME_ENERGY_SCHEMA)
#: Columns written last, and only when the user moves (docs/mobility.md): where the user sent
#: the request from, and each chosen server's link condition then, in ``servers`` order.
MOVEMENT_SCHEMA: dict[str, str] = {
    "user_x_m": "float",
    "user_y_m": "float",
    "conditions": "str",
}
MOVEMENT_COLUMNS: tuple[str, ...] = tuple(MOVEMENT_SCHEMA)
#: The separator of server indices in the ``servers`` column ("0;2;4").
SERVERS_SEPARATOR = ";"


@dataclass(frozen=True, slots=True)
class RequestRecord:
    """What one request achieved under one method.

    Attributes:
        method: the method's name (e.g. ``"Rand-2"``).
        step: the world step of the request.
        request_id: the core's request id.
        time_emit_s: when the user emitted it.
        latency_s: L_R (Eq. 2): the first reply's latency, or the fallback latency.
        target_s: τ (Eq. 4).
        servers: the chosen server indices, ascending.
        n_servers: n, the number of edge servers reachable.
        refused: copies refused (server at its load limit).
        fallback: True when every copy was refused and the on-device version answered.
        winner: server index of the first reply, -1 for a fallback.
        upload_s: Eq. 1 uploading terms (input + output) of the winning copy (NaN if fallback).
        propagation_s: Eq. 1 propagation terms of the winning copy (NaN if fallback).
        download_s: Eq. 1 downloading terms of the winning copy (NaN if fallback).
        compute_s: Eq. 1 compute term of the winning copy (NaN if fallback).
        reward: the Eq. 5 reward a learning method computed (NaN for methods that do not learn).
        epsilon: a learning method's exploration rate when it decided (NaN otherwise).
        lost: copies lost to a failed server (docs/failures_energy.md).
        end_reason: why the request ended (``edge.failures.END_REASONS``).
        server_energy_j: the servers' marginal energy of every copy (NaN when not priced).
        radio_energy_j: the user device's radio energy of every upload and download.
        saved_energy_j: the server energy cancelled copies did not spend.
    """

    method: str
    step: int
    request_id: Any
    time_emit_s: float
    latency_s: float
    target_s: float
    servers: tuple[int, ...]
    n_servers: int
    refused: int
    fallback: bool
    winner: int
    upload_s: float
    propagation_s: float
    download_s: float
    compute_s: float
    reward: float = math.nan
    epsilon: float = math.nan
    lost: int = 0
    end_reason: str = "reply"
    server_energy_j: float = math.nan
    radio_energy_j: float = math.nan
    saved_energy_j: float = 0.0

    @property
    def energy_j(self) -> float:
        """Everything the request's copies cost: the servers' and the device's radio."""
        return self.server_energy_j + self.radio_energy_j

    @property
    def n_selected(self) -> int:
        return len(self.servers)

    @property
    def access_rate(self) -> float:
        """|E_k| / n."""
        return len(self.servers) / self.n_servers

    @property
    def deviation_s(self) -> float:
        """Latency deviation τ - L_R."""
        return self.target_s - self.latency_s


#: How a ``requests.csv`` column is made from a record where it is not the record's attribute of
#: that name (a field or a property): the servers' text and the fallback as 0/1.
_COLUMN_VALUES: dict[str, Callable[[RequestRecord], Any]] = {
    "servers": lambda r: SERVERS_SEPARATOR.join(map(str, r.servers)),
    "fallback": lambda r: int(r.fallback),
}
#: The columns :func:`records_frame` writes, in file order: the contract's, then ``epsilon``,
#: then the outcome and energy columns.
RECORD_COLUMNS: tuple[str, ...] = (*REQUESTS_COLUMNS, "epsilon", *OUTCOME_ENERGY_COLUMNS)


def records_frame(records: Sequence[RequestRecord], phase: str, episode_steps: int,
                  movement: Movement | None = None) -> pd.DataFrame:
    """The ``requests.csv`` rows of one method and phase (:data:`RECORD_COLUMNS`, then
    :data:`MOVEMENT_COLUMNS` when the phase's user moves).

    Every column but ``phase`` and ``episode`` (which the records do not hold) is the record's
    attribute of that name, or its :data:`_COLUMN_VALUES` entry; the movement columns are read
    from the phase's ``movement`` at each record's step.
    """
    columns: dict[str, Any] = {}
    for name in RECORD_COLUMNS:
        if name == "phase":
            columns[name] = phase
        elif name == "episode":
            columns[name] = [r.step // episode_steps for r in records]
        elif name in _COLUMN_VALUES:
            columns[name] = [_COLUMN_VALUES[name](r) for r in records]
        else:
            columns[name] = [getattr(r, name) for r in records]
    if movement is not None:
        steps = [r.step for r in records]
        columns["user_x_m"] = movement.user_position_m[steps, 0] if steps else []
        columns["user_y_m"] = movement.user_position_m[steps, 1] if steps else []
        columns["conditions"] = [SERVERS_SEPARATOR.join(str(int(movement.conditions[r.step, server]))
                                                        for server in r.servers) for r in records]
    return pd.DataFrame(columns)
