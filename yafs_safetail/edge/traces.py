"""Loaders for the trace CSVs of ``traces/`` (formats in ``traces/README.md`` §1).

Every loader validates what it reads and raises :class:`TraceError` (a ``ValueError``) with a
one-line message naming the file, the field and, where useful, the row, counted as a spreadsheet
shows it: the header is row 1, the first data row row 2 (the file's line number; a blank line
counts, and is an error inside the data). Loaded arrays are read-only so a trace cannot be changed
by accident.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pandas as pd

# The default traces/ folder: the checkout's, or the installed package's copy.
from yafs_safetail.defaults import DEFAULT_TRACE_DIR as DEFAULT_TRACE_DIR
from yafs_safetail.edge import published as pub
from yafs_safetail.edge.usecases import USE_CASES

DIRECTIONS = ("uplink", "downlink")
PROPAGATION_CONDITIONS = tuple(pub.PROPAGATION_RTT_S)

GAMMA_COLUMNS: Mapping[int, tuple[str, ...]] = MappingProxyType(
    {number: use_case.gamma_columns for number, use_case in USE_CASES.items()}
)
"""Γ per use case besides n_processes (the use cases' definitions, edge/usecases.py)."""

COMPUTE_COLUMNS: Mapping[int, tuple[str, ...]] = MappingProxyType(
    {
        1: ("file_bytes", "width_px", "height_px", "n_processes", "latency_s"),
        2: ("file_bytes", "width_px", "height_px", "n_processes", "latency_s"),
        3: ("file_bytes", "duration_s", "n_processes", "latency_s"),
    }
)

LOAD_DEVICE_PREFIX = "device_"


class TraceError(ValueError):
    """A trace file is missing or malformed; the message names the file and the field."""


#: The first data row's number: the header is row 1, as a spreadsheet (and an editor's line
#: numbers) show a CSV.
FIRST_DATA_ROW = 2


def _at(path: Path, index: int, column: str) -> str:
    """Where a bad value is: the file, its row as a spreadsheet shows it, and its column."""
    return f"{path}: row {index + FIRST_DATA_ROW} (header = row 1), column {column!r}"


def _read_csv(path: Path | str, columns: tuple[str, ...]) -> tuple[Path, pd.DataFrame]:
    path = Path(path)
    if not path.is_file():
        raise TraceError(f"{path}: trace file not found")
    try:
        # Blank lines kept, so that a row's number is its line in the file (a blank line inside
        # the data is then a row of empty values, reported as such).
        frame = pd.read_csv(path, skip_blank_lines=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        fields = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(err))
        if fields:  # a row with more values than the header has columns
            expected, line, saw = fields.groups()
            raise TraceError(f"{path}: row {line} (header = row 1): {saw} values, the header has {expected} "
                             "columns") from None
        raise TraceError(f"{path}: not a readable CSV ({str(err).splitlines()[0]})") from err
    ends = np.flatnonzero(~frame.isna().all(axis=1).to_numpy())
    frame = frame.iloc[: ends[-1] + 1 if ends.size else 0]  # trailing blank lines: the file's end
    for column in columns:
        if column not in frame.columns:
            raise TraceError(f"{path}: missing column {column!r} (has {', '.join(map(str, frame.columns))})")
    if frame.empty:
        raise TraceError(f"{path}: no data rows")
    return path, frame


def _numeric(path: Path, frame: pd.DataFrame, column: str, *, positive: bool, integer: bool = False) -> np.ndarray:
    """The column as float64, rejecting non-numbers, NaN, negatives (or zeros) and fractions."""
    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raw = frame[column].iloc[bad[0]]
        shown = "NaN/empty" if pd.isna(raw) else repr(raw) if isinstance(raw, str) else str(raw)
        raise TraceError(f"{_at(path, bad[0], column)}: {shown} is not a finite number")
    bad = np.flatnonzero(values <= 0 if positive else values < 0)
    if bad.size:
        need = "> 0" if positive else ">= 0"
        raise TraceError(f"{_at(path, bad[0], column)}: {values[bad[0]]:g} must be {need}")
    if integer:
        bad = np.flatnonzero(values != np.floor(values))
        if bad.size:
            raise TraceError(f"{_at(path, bad[0], column)}: {values[bad[0]]:g} is not an integer")
    return values


def _frozen(values: np.ndarray) -> np.ndarray:
    values = np.ascontiguousarray(values)
    values.setflags(write=False)
    return values


@dataclass(frozen=True)
class BandwidthTrace:
    """Throughput pools per contention level and direction.

    Attributes:
        uplink_bps: index = contention level (extra contending devices), each a 1-D pool.
        downlink_bps: same for the downlink.
        source: the file it was read from.
    """

    uplink_bps: tuple[np.ndarray, ...]
    downlink_bps: tuple[np.ndarray, ...]
    source: Path

    @property
    def max_contention_level(self) -> int:
        return len(self.uplink_bps) - 1

    def samples_bps(self, contention_level: int, direction: str) -> np.ndarray:
        """The pool of one (level, direction).

        Raises:
            TraceError: level outside 0..max_contention_level or unknown direction.
        """
        if direction not in DIRECTIONS:
            raise TraceError(f"{self.source}: direction {direction!r} is not one of {DIRECTIONS}")
        if not 0 <= contention_level <= self.max_contention_level:
            raise TraceError(
                f"{self.source}: contention_level {contention_level} outside 0..{self.max_contention_level}"
            )
        pools = self.uplink_bps if direction == "uplink" else self.downlink_bps
        return pools[contention_level]


def load_bandwidth(path: Path | str) -> BandwidthTrace:
    """Read ``bandwidth.csv``: every level 0..max present for both directions, throughput > 0."""
    path, frame = _read_csv(path, ("contention_level", "direction", "throughput_bps"))
    level = _numeric(path, frame, "contention_level", positive=False, integer=True).astype(np.int64)
    throughput = _numeric(path, frame, "throughput_bps", positive=True)
    direction = frame["direction"].astype(str).to_numpy()
    bad = np.flatnonzero(~np.isin(direction, DIRECTIONS))
    if bad.size:
        raise TraceError(
            f"{_at(path, bad[0], 'direction')}: {direction[bad[0]]!r} is not one of {DIRECTIONS}"
        )
    pools: dict[str, list[np.ndarray]] = {d: [] for d in DIRECTIONS}
    for lvl in range(int(level.max()) + 1):
        for d in DIRECTIONS:
            pool = throughput[(level == lvl) & (direction == d)]
            if pool.size == 0:
                raise TraceError(f"{path}: field 'contention_level': no {d} rows for level {lvl}")
            pools[d].append(_frozen(pool))
    return BandwidthTrace(tuple(pools["uplink"]), tuple(pools["downlink"]), path)


@dataclass(frozen=True)
class PropagationTrace:
    """Ping RTT pools per signal condition.

    Attributes:
        rtt_s: condition -> 1-D pool of round-trip times in seconds.
        source: the file it was read from.
    """

    rtt_s: Mapping[int, np.ndarray]
    source: Path

    @property
    def conditions(self) -> tuple[int, ...]:
        return tuple(sorted(self.rtt_s))

    def samples_s(self, condition: int) -> np.ndarray:
        """The RTT pool of one condition.

        Raises:
            TraceError: unknown condition.
        """
        if condition not in self.rtt_s:
            raise TraceError(f"{self.source}: condition {condition!r} unknown (known: {self.conditions})")
        return self.rtt_s[condition]

    def median_s(self, condition: int) -> float:
        """ρ^μ of the paper's Definition 1 for a server at this condition."""
        return float(np.median(self.samples_s(condition)))


def load_propagation(path: Path | str) -> PropagationTrace:
    """Read ``propagation.csv``: conditions 1..5 only, each present, RTT > 0."""
    path, frame = _read_csv(path, ("condition", "rtt_s"))
    condition = _numeric(path, frame, "condition", positive=True, integer=True).astype(np.int64)
    rtt = _numeric(path, frame, "rtt_s", positive=True)
    bad = np.flatnonzero(~np.isin(condition, PROPAGATION_CONDITIONS))
    if bad.size:
        raise TraceError(
            f"{_at(path, bad[0], 'condition')}: {condition[bad[0]]} is not one of {PROPAGATION_CONDITIONS}"
        )
    pools = {}
    for c in PROPAGATION_CONDITIONS:
        pool = rtt[condition == c]
        if pool.size == 0:
            raise TraceError(f"{path}: field 'condition': no rows for condition {c}")
        pools[c] = _frozen(pool)
    return PropagationTrace(MappingProxyType(pools), path)


@dataclass(frozen=True)
class ComputeTrace:
    """One use case's compute trace.

    Attributes:
        use_case: 1, 2 or 3.
        frame: the CSV's columns (``COMPUTE_COLUMNS[use_case]``), validated.
        source: the file it was read from.
    """

    use_case: int
    frame: pd.DataFrame
    source: Path

    @property
    def gamma_columns(self) -> tuple[str, ...]:
        """Γ inputs of the compute model besides ``n_processes``."""
        return GAMMA_COLUMNS[self.use_case]

    def gamma_matrix(self) -> np.ndarray:
        """Γ per row, shape (rows, len(gamma_columns)), float64."""
        return self.frame.loc[:, list(self.gamma_columns)].to_numpy(dtype=float).reshape(len(self.frame), -1)

    @property
    def n_processes(self) -> np.ndarray:
        return self.frame["n_processes"].to_numpy(dtype=np.int64)

    @property
    def latency_s(self) -> np.ndarray:
        return self.frame["latency_s"].to_numpy(dtype=float)


def load_compute(path: Path | str, use_case: int) -> ComputeTrace:
    """Read ``compute_uc{use_case}.csv``: sizes and latency > 0, n_processes in 1..5."""
    if use_case not in COMPUTE_COLUMNS:
        raise TraceError(f"{path}: use_case {use_case!r} is not one of {tuple(COMPUTE_COLUMNS)}")
    columns = COMPUTE_COLUMNS[use_case]
    path, frame = _read_csv(path, columns)
    clean = {}
    for column in columns:
        integer = column in ("file_bytes", "width_px", "height_px", "n_processes")
        clean[column] = _numeric(path, frame, column, positive=True, integer=integer)
    k = clean["n_processes"]
    bad = np.flatnonzero(k > pub.MAX_PROCESSES)
    if bad.size:
        raise TraceError(
            f"{_at(path, bad[0], 'n_processes')}: {k[bad[0]]:g} outside 1..{pub.MAX_PROCESSES}"
        )
    missing = sorted(set(range(1, pub.MAX_PROCESSES + 1)) - set(k.astype(int)))
    if missing:
        raise TraceError(f"{path}: field 'n_processes': no rows for k = {missing}")
    out = pd.DataFrame(
        {c: clean[c].astype(np.int64) if c in ("file_bytes", "width_px", "height_px", "n_processes") else clean[c]
         for c in columns}
    )
    return ComputeTrace(use_case, out, path)


@dataclass(frozen=True)
class LoadTrace:
    """Active users per edge device and minute.

    Attributes:
        users: shape (minutes, devices), int64, row t = minute t.
        device_names: the CSV's device columns in order (``device_0``, ...).
        source: the file it was read from.
    """

    users: np.ndarray
    device_names: tuple[str, ...]
    source: Path

    @property
    def n_minutes(self) -> int:
        return int(self.users.shape[0])

    @property
    def n_devices(self) -> int:
        return int(self.users.shape[1])

    def levels(self, max_level: int = pub.MAX_LOAD_PER_SERVER) -> np.ndarray:
        """Per-device min-max scaled integer levels; see :func:`scale_load_levels`."""
        return scale_load_levels(self.users, max_level)


def load_load_trace(path: Path | str) -> LoadTrace:
    """Read ``load.csv``: minute 0..n-1 in order, >= 1 device column, integer counts >= 0."""
    path, frame = _read_csv(path, ("minute",))
    devices = tuple(str(c) for c in frame.columns if str(c).startswith(LOAD_DEVICE_PREFIX))
    if not devices:
        raise TraceError(f"{path}: no '{LOAD_DEVICE_PREFIX}N' columns")
    minute = _numeric(path, frame, "minute", positive=False, integer=True)
    bad = np.flatnonzero(minute != np.arange(minute.size))
    if bad.size:
        raise TraceError(f"{_at(path, bad[0], 'minute')}: {minute[bad[0]]:g}, expected {bad[0]}")
    users = np.column_stack([_numeric(path, frame, d, positive=False, integer=True) for d in devices])
    return LoadTrace(_frozen(users.astype(np.int64)), devices, path)


def scale_load_levels(users: np.ndarray, max_level: int = pub.MAX_LOAD_PER_SERVER) -> np.ndarray:
    """Min-max scale each column (device) into integer levels 0..max_level.

    ``level = floor(max_level * (users - min) / (max - min) + 0.5)``: rounding half up, so a value
    exactly between two levels always goes up (NumPy's ``rint`` would round half to even). A
    constant column maps to 0.

    Args:
        users: shape (minutes, devices) or (minutes,), counts.
        max_level: the top level (default: Table I's per-server capacity 4).

    Returns:
        int64 array of the same shape.

    Raises:
        ValueError: max_level < 1.
    """
    if max_level < 1:
        raise ValueError(f"max_level: {max_level} must be >= 1")
    values = np.asarray(users, dtype=float)
    lo = values.min(axis=0)
    span = values.max(axis=0) - lo
    fraction = np.divide(values - lo, span, out=np.zeros_like(values), where=span > 0)
    return np.floor(max_level * fraction + 0.5).astype(np.int64)


@dataclass(frozen=True)
class TraceSet:
    """Every trace the edge model needs, loaded from one folder."""

    bandwidth: BandwidthTrace
    propagation: PropagationTrace
    compute: Mapping[int, ComputeTrace]
    load: LoadTrace
    directory: Path


def load_traces(directory: Path | str = DEFAULT_TRACE_DIR) -> TraceSet:
    """Load and validate all trace files of ``directory`` (default: the repository's traces/)."""
    directory = Path(directory)
    if not directory.is_dir():
        raise TraceError(f"{directory}: trace directory not found")
    return TraceSet(
        bandwidth=load_bandwidth(directory / "bandwidth.csv"),
        propagation=load_propagation(directory / "propagation.csv"),
        compute=MappingProxyType(
            {uc: load_compute(directory / f"compute_uc{uc}.csv", uc) for uc in pub.USE_CASES}
        ),
        load=load_load_trace(directory / "load.csv"),
        directory=directory,
    )


#: Every file of a traces folder a run reads, relative to it: the CSVs and each use case's compute
#: model as the NumPy forward pass loads it (``edge.compute.ComputeModel.load``; the ``.keras``
#: copies are read only by the tests).
READ_FILES: tuple[str, ...] = (
    "bandwidth.csv", "propagation.csv", *(f"compute_uc{uc}.csv" for uc in pub.USE_CASES), "load.csv",
    *(f"models/compute_uc{uc}{suffix}" for uc in pub.USE_CASES for suffix in (".npz", ".json")))


def same_traces(directory: Path | str, other: Path | str = DEFAULT_TRACE_DIR) -> bool:
    """Whether two traces folders hold the same bytes in every file a run reads (a copy of the
    packaged traces is the packaged traces: its runs are theirs, titles and all)."""
    first, second = Path(directory), Path(other)
    for name in READ_FILES:
        a, b = first / name, second / name
        if not (a.is_file() and b.is_file()) or a.read_bytes() != b.read_bytes():
            return False
    return True
