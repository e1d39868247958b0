"""The two YAFS results files, written with buffering.

``<path>.csv``: one row per message processed by a module (``COMP_M``) or a sink
(``SINK_M``). ``<path>_link.csv``: one row per hop (``LINK``). Values are written with
Python's ``repr`` of floats, so the files are byte-identical across runs with the same seed.
"""

from __future__ import annotations

import csv
import os
from operator import itemgetter
from typing import Any

EVENT_COLUMNS = (
    "id", "type", "app", "module", "message", "DES.src", "DES.dst", "TOPO.src", "TOPO.dst",
    "module.src", "service", "time_in", "time_out", "time_emit", "time_reception",
)
LINK_COLUMNS = ("id", "type", "src", "dst", "app", "latency", "message", "ctime", "size", "buffer")

# Columns that can hold text or None (names, node and process ids, ids of messages); the
# others are always numbers, which ``%s`` writes exactly as ``csv`` does.
_EVENT_TEXT = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9)
_LINK_TEXT = (0, 1, 2, 3, 4, 6, 8)
_EVENT_FORMAT = ",".join(["%s"] * len(EVENT_COLUMNS)) + "\r\n"
_LINK_FORMAT = ",".join(["%s"] * len(LINK_COLUMNS)) + "\r\n"
_SPECIAL = frozenset(',"\r\n')


_NUMBERS = frozenset((int, float, bool))


def _plain(rows: list[tuple[Any, ...]], columns: tuple[int, ...], safe: set[Any]) -> bool:
    """True if ``%s`` formatting of ``rows`` gives exactly ``csv.writer``'s output: no None
    (csv writes nothing), and no text that csv would quote (commas, quotes, line breaks).

    ``safe`` holds values already found harmless (names, node ids); it grows, so each
    distinct value is examined once per file.
    """
    for column in columns:
        values = set(map(itemgetter(column), rows))
        if _NUMBERS.issuperset(map(type, values)):
            continue
        for value in values - safe:
            if value is None:
                return False
            text = value if type(value) is str else str(value)
            if text == "" or not _SPECIAL.isdisjoint(text):
                return False
            if type(value) is not float:
                safe.add(value)
    return True


class Metrics:
    """Buffered CSV writer for the event and link results.

    The core appends row tuples to :attr:`event_rows` / :attr:`link_rows` and calls
    :meth:`flush` when a buffer exceeds :attr:`buffer_rows`.

    Args:
        default_results_path: results path without extension (YAFS default ``"result"``).
        enabled: False keeps no rows at all (for runs that only need request outcomes).
        buffer_rows: rows kept in memory before writing.
    """

    # YAFS3's names of the derived time columns and of the two energy views (``Stats``).
    TIME_LATENCY = "time_latency"
    TIME_WAIT = "time_wait"
    TIME_RESPONSE = "time_response"
    TIME_SERVICE = "time_service"
    TIME_TOTAL_RESPONSE = "time_total_response"
    WATT_SERVICE = "byService"
    WATT_UPTIME = "byUptime"

    def __init__(
        self,
        default_results_path: str | os.PathLike[str] | None = None,
        *,
        enabled: bool = True,
        buffer_rows: int = 20000,
    ) -> None:
        self.path = os.fspath(default_results_path) if default_results_path is not None else "result"
        self.enabled = enabled
        self.buffer_rows = buffer_rows
        self.event_rows: list[tuple[Any, ...]] = []
        self.link_rows: list[tuple[Any, ...]] = []
        self.rows_written = 0
        self._files: tuple[Any, Any] | None = None
        self._writers: tuple[Any, Any] | None = None
        self._started = False
        self._safe_values: set[Any] = set()

    @property
    def event_path(self) -> str:
        """Path of the module/sink results file."""
        return f"{self.path}.csv"

    @property
    def link_path(self) -> str:
        """Path of the link results file."""
        return f"{self.path}_link.csv"

    def open(self) -> None:
        """Open both files: truncate and write headers the first time, append afterwards."""
        if not self.enabled or self._files is not None:
            return
        mode = "a" if self._started else "w"
        event_file = open(self.event_path, mode, newline="", encoding="utf-8")  # noqa: SIM115
        link_file = open(self.link_path, mode, newline="", encoding="utf-8")  # noqa: SIM115
        self._files = (event_file, link_file)
        self._writers = (csv.writer(event_file), csv.writer(link_file))
        if not self._started:
            self._writers[0].writerow(EVENT_COLUMNS)
            self._writers[1].writerow(LINK_COLUMNS)
            self._started = True

    def insert(self, value: dict[str, Any]) -> None:
        """Add an event row given as a dict with the :data:`EVENT_COLUMNS` keys (YAFS API)."""
        if self.enabled:
            self.event_rows.append(tuple(value[c] for c in EVENT_COLUMNS))

    def insert_link(self, value: dict[str, Any]) -> None:
        """Add a link row given as a dict with the :data:`LINK_COLUMNS` keys (YAFS API)."""
        if self.enabled:
            self.link_rows.append(tuple(value[c] for c in LINK_COLUMNS))

    def flush(self) -> None:
        """Write buffered rows to disk."""
        if not self.enabled:
            return
        if self._writers is None:
            self.open()
        assert self._writers is not None and self._files is not None
        for rows, text_columns, line_format, index in (
            (self.event_rows, _EVENT_TEXT, _EVENT_FORMAT, 0),
            (self.link_rows, _LINK_TEXT, _LINK_FORMAT, 1),
        ):
            if not rows:
                continue
            # Same bytes as csv.writer, faster: plain %s formatting when nothing needs quoting.
            if _plain(rows, text_columns, self._safe_values):
                self._files[index].write("".join([line_format % row for row in rows]))
            else:
                self._writers[index].writerows(rows)
        self.rows_written += len(self.event_rows) + len(self.link_rows)
        self.event_rows.clear()
        self.link_rows.clear()
        self._files[0].flush()
        self._files[1].flush()

    def close(self) -> None:
        """Flush and close the files (a later :meth:`open` appends)."""
        if self._files is None:
            return
        self.flush()
        for handle in self._files:
            handle.close()
        self._files = None
        self._writers = None
