"""When each edge server is down: the one failure model both worlds use (beyond the paper).

A server alternates between up and down. By default its times to failure and to repair are
exponential (means ``mttf_s`` and ``mttr_s``), drawn once per phase from the phase's own
``"failures"`` stream (common random numbers: every method meets the same outages), and each
server starts in its stationary state (down with probability ``mttr / (mttf + mttr)``), so the
chance that a server is down at any instant is that unavailability from the first request on.
A CSV of down intervals (``server,down_s,up_s``, one scripted outage per row, as YAFS's
failure examples remove a node at a time and bring it back) replaces or adds to the draws.

A copy sent to a server that is down on arrival, or that goes down before the copy's reply
has left it, is lost: the user never hears of it and learns only by its time-out
(:func:`effective_timeout_s`). Nothing here knows about requests or methods.
"""

from __future__ import annotations

import csv
import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# The settings hold no arrays: they live in a module without NumPy, so that the commands' options
# (a failure sweep's mean repair time) are declared before anything heavy loads.
from yafs_safetail.edge.failure_settings import DEFAULT_MTTR_S as DEFAULT_MTTR_S
from yafs_safetail.edge.failure_settings import FailureSettings as FailureSettings

#: Why a request ended (``requests.csv``'s ``end_reason``).
END_REPLY = "reply"  # a copy's reply arrived within the time-out
END_ALL_REFUSED = "all_refused"  # every copy was refused: the on-device fallback at once
END_ALL_LOST = "all_lost"  # every copy not refused was lost to a failure: fallback after the time-out
END_TIMEOUT = "timeout"  # no reply within the time-out, not every copy lost: fallback after it
END_REASONS: tuple[str, ...] = (END_REPLY, END_ALL_REFUSED, END_ALL_LOST, END_TIMEOUT)


class FailureFileError(ValueError):
    """A down-intervals file that cannot be used (one line: file, row, field, what is wrong)."""


def effective_timeout_s(settings: FailureSettings, worst_case_copy_latency_s: float) -> float:
    """How long the user waits for a reply.

    A time-out the user set is used as it is. Otherwise, with failures on, the world's
    worst-case latency of a live, uncontended copy: a reply later than that can only come
    from a lost copy, so the user never gives up on a copy that would still answer. With
    failures off there is no time-out (``inf``), so every latency is the paper's.
    """
    if settings.timeout_s is not None:
        return float(settings.timeout_s)
    return float(worst_case_copy_latency_s) if settings.enabled else math.inf


@dataclass(frozen=True)
class DownIntervals:
    """Each server's outages: sorted, disjoint ``[down_s, up_s)`` intervals.

    Attributes:
        starts_s: per server, the outages' start times (ascending).
        ends_s: per server, the matching end times.
    """

    starts_s: tuple[tuple[float, ...], ...]
    ends_s: tuple[tuple[float, ...], ...]

    @classmethod
    def none(cls, n_servers: int) -> DownIntervals:
        return cls(tuple(() for _ in range(n_servers)), tuple(() for _ in range(n_servers)))

    @classmethod
    def from_lists(cls, intervals: Sequence[Sequence[tuple[float, float]]]) -> DownIntervals:
        """From each server's ``(down_s, up_s)`` pairs, in any order, overlaps merged."""
        starts: list[tuple[float, ...]] = []
        ends: list[tuple[float, ...]] = []
        for server_intervals in intervals:
            merged: list[list[float]] = []
            for down_s, up_s in sorted(server_intervals):
                if merged and down_s <= merged[-1][1]:
                    merged[-1][1] = max(merged[-1][1], up_s)
                else:
                    merged.append([float(down_s), float(up_s)])
            starts.append(tuple(interval[0] for interval in merged))
            ends.append(tuple(interval[1] for interval in merged))
        return cls(tuple(starts), tuple(ends))

    @property
    def n_servers(self) -> int:
        return len(self.starts_s)

    def merged_with(self, other: DownIntervals) -> DownIntervals:
        """Both sets of outages (a server is down when either says so)."""
        if other.n_servers != self.n_servers:
            raise ValueError(f"down intervals: {other.n_servers} servers, expected {self.n_servers}")
        return DownIntervals.from_lists([
            list(zip(self.starts_s[i] + other.starts_s[i], self.ends_s[i] + other.ends_s[i], strict=True))
            for i in range(self.n_servers)
        ])

    def is_down(self, server: int, time_s: float) -> bool:
        """Whether ``server`` is down at ``time_s``."""
        index = bisect_right(self.starts_s[server], time_s) - 1
        return index >= 0 and time_s < self.ends_s[server][index]

    def first_failure_s(self, server: int, start_s: float, end_s: float) -> float | None:
        """When ``server`` is first down in ``[start_s, end_s]`` (``start_s`` itself when it is
        down already), or None when it stays up throughout."""
        if self.is_down(server, start_s):
            return float(start_s)
        index = bisect_right(self.starts_s[server], start_s)
        starts = self.starts_s[server]
        if index < len(starts) and starts[index] <= end_s:
            return float(starts[index])
        return None

    def up_fraction(self, server: int, horizon_s: float) -> float:
        """The share of ``[0, horizon_s)`` the server was up."""
        down_s = sum(max(0.0, min(end, horizon_s) - start)
                     for start, end in zip(self.starts_s[server], self.ends_s[server], strict=True)
                     if start < horizon_s)
        return 1.0 - down_s / horizon_s


def draw_down_intervals(settings: FailureSettings, n_servers: int, horizon_s: float,
                        rng: np.random.Generator) -> DownIntervals:
    """Random outages of every server over ``[0, horizon_s]`` (none when ``mttf_s`` is None).

    Each server starts down with the stationary probability, then alternates exponential
    up and down times; servers are independent. Draws come from ``rng`` server by server, so
    a phase's outages depend only on its seed.
    """
    if settings.mttf_s is None:
        return DownIntervals.none(n_servers)
    per_server: list[list[tuple[float, float]]] = []
    for _ in range(n_servers):
        intervals: list[tuple[float, float]] = []
        down = bool(rng.random() < settings.unavailability)
        time_s = 0.0
        while time_s <= horizon_s:
            if down:
                up_s = time_s + float(rng.exponential(settings.mttr_s))
                intervals.append((time_s, up_s))
                time_s = up_s
            else:
                time_s += float(rng.exponential(settings.mttf_s))
            down = not down
        per_server.append(intervals)
    return DownIntervals.from_lists(per_server)


def read_down_file(path: Path, n_servers: int) -> DownIntervals:
    """Scripted outages from a CSV with the header ``server,down_s,up_s`` (server indices
    0..n-1, times in seconds from the phase's start, ``down_s < up_s``).

    Raises:
        FailureFileError: one line naming the file, the row and the field.
    """
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle)
            fields = tuple(reader.fieldnames or ())
            missing = [name for name in ("server", "down_s", "up_s") if name not in fields]
            if missing:
                raise FailureFileError(f"{path}: missing column(s) {', '.join(missing)} "
                                       "(expected the header server,down_s,up_s)")
            per_server: list[list[tuple[float, float]]] = [[] for _ in range(n_servers)]
            for row_number, row in enumerate(reader, start=2):
                per_server_index, down_s, up_s = _checked_row(path, row_number, row, n_servers)
                per_server[per_server_index].append((down_s, up_s))
    except OSError as error:
        raise FailureFileError(f"{path}: cannot read the down-intervals file ({error.strerror})") from None
    return DownIntervals.from_lists(per_server)


def _checked_row(path: Path, row_number: int, row: dict[str, str | None],
                 n_servers: int) -> tuple[int, float, float]:
    where = f"{path}: row {row_number}"
    raw_server = (row.get("server") or "").strip()
    try:
        server = int(raw_server)
    except ValueError:
        raise FailureFileError(f"{where}: field server: not a server index: {raw_server!r}") from None
    if not 0 <= server < n_servers:
        raise FailureFileError(f"{where}: field server: {server} is not one of the {n_servers} servers "
                               f"(0..{n_servers - 1})")
    times: list[float] = []
    for name in ("down_s", "up_s"):
        raw = (row.get(name) or "").strip()
        try:
            value = float(raw)
        except ValueError:
            raise FailureFileError(f"{where}: field {name}: not a number of seconds: {raw!r}") from None
        if not (math.isfinite(value) and value >= 0):
            raise FailureFileError(f"{where}: field {name}: must be a time >= 0, got {raw!r}")
        times.append(value)
    if not times[0] < times[1]:
        raise FailureFileError(f"{where}: field up_s: must be after down_s ({times[1]} <= {times[0]})")
    return server, times[0], times[1]


def phase_down_intervals(settings: FailureSettings, n_servers: int, horizon_s: float,
                         rng: np.random.Generator) -> DownIntervals:
    """A phase's outages: the random draws (from ``rng``) and the scripted file together."""
    drawn = draw_down_intervals(settings, n_servers, horizon_s, rng)
    if settings.down_file is None:
        return drawn
    return drawn.merged_with(read_down_file(settings.down_file, n_servers))
