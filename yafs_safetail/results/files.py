"""The results folder's files: names, schemas, atomic writing, and checked readers.

The single source of truth for the folder contract of ``docs/results.md``: every file is
written to a temporary name in the same folder and then renamed, and floats are written as
their shortest round-trip repr, so the same data always gives byte-identical files and reading
a file back gives exactly the numbers that were written.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.edge.failures import END_REASONS
from yafs_safetail.record import (
    OUTCOME_ENERGY_SCHEMA,
    PHASES,
    REQUESTS_COLUMNS,
    REQUESTS_SCHEMA,
    SERVERS_SEPARATOR,
)

REQUESTS_FILE = "requests.csv"
RUN_FILE = "run.json"
SUMMARY_CSV_FILE = "summary.csv"
SUMMARY_MD_FILE = "summary.md"
PERCENTILES: tuple[int, ...] = (50, 90, 95, 99)

SUMMARY_COLUMNS: tuple[str, ...] = (
    "method",
    "preset",
    "n_requests",
    "p50_s",
    "p90_s",
    "p95_s",
    "p99_s",
    "mean_s",
    "mean_access_rate",
    "mean_n_selected",
    "median_n_selected",
    "min_n_selected",
    "max_n_selected",
    "mean_target_s",
    "mean_deviation_s",
    "target_met_rate",
    "fallback_rate",
    "mean_refused",
    "mean_abs_reward",
    "min_window_n_selected",
    "max_window_n_selected",
    "thin_percentiles",
    "success_rate",
    "all_refused_rate",
    "all_lost_rate",
    "timeout_rate",
    "energy_j_per_request",
)
#: How each request ended (``requests.csv``'s ``end_reason``): the summary's share of each.
END_REASON_RATE_COLUMNS: dict[str, str] = {"reply": "success_rate", "all_refused": "all_refused_rate",
                                           "all_lost": "all_lost_rate", "timeout": "timeout_rate"}
#: Summary columns added after the first release: a summary.csv written before them reads with
#: NaN there (``thin_percentiles``: computed from ``n_requests``, as it is a function of it).
OPTIONAL_SUMMARY_COLUMNS: tuple[str, ...] = ("min_window_n_selected", "max_window_n_selected",
                                             "thin_percentiles", *END_REASON_RATE_COLUMNS.values(),
                                             "energy_j_per_request")

#: A percentile is trusted when at least this many test requests lie beyond it: the q-th
#: percentile of n requests rests on the n·(1 − q) slowest ones, and with fewer than 10 of them
#: it moves with the luck of a handful of requests (p99 needs 1,000 test requests).
MIN_REQUESTS_BEYOND_PERCENTILE = 10
#: Joins the names in the ``thin_percentiles`` column.
THIN_SEPARATOR = ";"


def thin_percentiles(n_requests: int) -> tuple[int, ...]:
    """The percentiles of ``PERCENTILES`` with fewer than ``MIN_REQUESTS_BEYOND_PERCENTILE``
    of ``n_requests`` requests beyond them: n·(1 − q/100) < 10.

    Integer arithmetic (n·(100 − q) < 1000), so 1,000 requests are exactly enough for p99.
    """
    return tuple(p for p in PERCENTILES
                 if n_requests * (100 - p) < MIN_REQUESTS_BEYOND_PERCENTILE * 100)


def thin_percentiles_text(n_requests: int) -> str:
    """``thin_percentiles`` as the summary column writes it: e.g. ``p95;p99``; empty: none."""
    return THIN_SEPARATOR.join(f"p{p}" for p in thin_percentiles(n_requests))

# Floats are written as Python's shortest round-trip repr: deterministic (identical data gives
# identical bytes) and lossless, so a summary recomputed from requests.csv equals the one
# computed in memory before writing it, to the last bit.
FLOAT_FORMAT = None
NA_REP = "NaN"

class ResultsFileError(ValueError):
    """A results file is missing or does not follow the contract (one-line message)."""


# --------------------------------------------------------------------------------------------
# Atomic, deterministic writing


def _umask() -> int:
    # The only way to read the umask is to set it; it is put back at once.
    umask = os.umask(0)
    os.umask(umask)
    return umask


def file_mode() -> int:
    """Permission bits an ordinary ``open(..., "w")`` would give (temporary files get 0600)."""
    return 0o666 & ~_umask()


def folder_mode() -> int:
    """Permission bits an ordinary ``mkdir`` would give (``tempfile.mkdtemp`` gives 0700)."""
    return 0o777 & ~_umask()


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename.

    Args:
        path: the destination file; its folder must exist.
        text: the content (written as UTF-8 with "\\n" line ends).

    Returns:
        The destination path.
    """
    dest = Path(path)
    handle, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=dest.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="\n") as stream:
            stream.write(text)
        os.chmod(tmp_name, file_mode())
        os.replace(tmp_name, dest)
    except BaseException:
        if os.path.exists(tmp_name):
            os.unlink(tmp_name)
        raise
    return dest


def _csv_text(frame: pd.DataFrame) -> str:
    return frame.to_csv(index=False, float_format=FLOAT_FORMAT, na_rep=NA_REP, lineterminator="\n")


def _require_columns(frame: pd.DataFrame, columns: Sequence[str], what: str) -> None:
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ValueError(f"{what}: missing column(s) {', '.join(missing)}")


def write_requests_csv(requests: pd.DataFrame, directory: str | os.PathLike[str]) -> Path:
    """Write ``requests.csv`` into ``directory`` (contract columns first, in contract order).

    Columns beyond the contract are kept after the contract ones, in their given order.

    Args:
        requests: one row per request and method, with every column of ``REQUESTS_COLUMNS``.
        directory: the results folder (must exist).

    Returns:
        The written path.

    Raises:
        ValueError: a contract column is missing.
    """
    _require_columns(requests, REQUESTS_COLUMNS, "requests table")
    extras = [c for c in requests.columns if c not in REQUESTS_SCHEMA]
    ordered = requests.loc[:, [*REQUESTS_COLUMNS, *extras]]
    return write_text_atomic(Path(directory) / REQUESTS_FILE, _csv_text(ordered))


# --------------------------------------------------------------------------------------------
# Reading requests.csv


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _results_file(path: str | os.PathLike[str], name: str) -> Path:
    """``path`` itself, or the file ``name`` inside it when it is a results folder; must exist."""
    file = Path(path)
    if file.is_dir():
        file = file / name
    if not file.is_file():
        raise ResultsFileError(f"{file}: file not found")
    return file


def read_requests_csv(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read and check a ``requests.csv`` (or the one inside a results folder).

    Args:
        path: the file, or the results folder holding it.

    Returns:
        The table with contract dtypes (int64 / float64 / str) and rows in file order.

    Raises:
        ResultsFileError: the file is missing or unreadable, a column is missing, or a value
            is of the wrong kind; the one-line message names the file, the column and, for a
            bad value, the line.
    """
    file = _results_file(path, REQUESTS_FILE)
    typed = {**REQUESTS_SCHEMA, **OUTCOME_ENERGY_SCHEMA}
    text_columns = [c for c, kind in typed.items() if kind == "str"]
    try:
        raw = pd.read_csv(file, dtype={c: str for c in text_columns}, low_memory=False)
    except pd.errors.EmptyDataError:
        raise ResultsFileError(f"{file}: file is empty (expected a header line)") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as error:
        raise ResultsFileError(f"{file}: not a readable CSV file: {_one_line(error)}") from None
    missing = [c for c in REQUESTS_COLUMNS if c not in raw.columns]
    if missing:
        raise ResultsFileError(f"{file}: missing column(s) {', '.join(missing)}")
    out = pd.DataFrame(index=raw.index)
    # The contract columns, then the others in file order; the outcome and energy columns came
    # later, and are typed and checked when the file has them.
    for column in [*REQUESTS_COLUMNS, *(c for c in raw.columns if c not in REQUESTS_SCHEMA)]:
        kind = typed.get(column)
        values = raw[column]
        if kind is None:
            out[column] = values
            continue
        if kind == "str":
            out[column] = values.fillna("").astype(str)
            continue
        numbers = pd.to_numeric(values, errors="coerce")
        bad = numbers.isna() & values.notna()
        if kind == "int":
            bad |= values.isna() | (numbers.notna() & (numbers != np.floor(numbers)))
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise ResultsFileError(
                f"{file}: column {column}, line {row + 2}: "
                f"expected {'an integer' if kind == 'int' else 'a number'}, got {values.iloc[row]!r}"
            )
        out[column] = numbers.astype("int64" if kind == "int" else "float64")
    _check_requests_values(out, file)
    return out


def _first_bad(file: Path, mask: pd.Series, column: str, frame: pd.DataFrame, what: str) -> None:
    if mask.any():
        row = int(np.flatnonzero(mask.to_numpy())[0])
        raise ResultsFileError(
            f"{file}: column {column}, line {row + 2}: {what}, got {frame[column].iloc[row]!r}"
        )


def _check_requests_values(frame: pd.DataFrame, file: Path) -> None:
    if "end_reason" in frame.columns:
        _first_bad(file, ~frame["end_reason"].isin(END_REASONS), "end_reason", frame,
                   f"expected one of {', '.join(END_REASONS)}")
    if "lost" in frame.columns:
        _first_bad(file, frame["lost"] < 0, "lost", frame, "expected a count >= 0")
    _first_bad(file, frame["method"] == "", "method", frame, "method name is empty")
    _first_bad(file, ~frame["phase"].isin(PHASES), "phase", frame, "expected 'train' or 'test'")
    for column in ("latency_s", "target_s"):
        values = frame[column]
        _first_bad(file, ~np.isfinite(values) | (values < 0), column, frame,
                   "expected a finite non-negative number")
    _first_bad(file, ~frame["fallback"].isin((0, 1)), "fallback", frame, "expected 0 or 1")
    _first_bad(file, frame["n_selected"] < 1, "n_selected", frame, "expected at least 1")
    _first_bad(file, frame["refused"] < 0, "refused", frame, "expected a count >= 0")
    access = frame["access_rate"]
    _first_bad(file, ~((access > 0) & (access <= 1)), "access_rate", frame,
               "expected a share in (0, 1]")
    n_listed = frame["servers"].str.count(SERVERS_SEPARATOR) + (frame["servers"] != "")
    _first_bad(file, n_listed != frame["n_selected"], "servers", frame,
               "expected n_selected server indices joined by ';'")
    # Catches the easy sign slip (latency − target): the paper's deviation is target − achieved.
    expected = frame["target_s"] - frame["latency_s"]
    tolerance = 1e-9 * np.maximum(1.0, np.abs(frame["target_s"]))
    _first_bad(file, ~(np.abs(frame["deviation_s"] - expected) <= tolerance), "deviation_s",
               frame, "expected target_s − latency_s")


def read_summary_csv(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read a ``summary.csv`` (or the one inside a results folder).

    Raises:
        ResultsFileError: missing or unreadable file, or a missing column.
    """
    file = _results_file(path, SUMMARY_CSV_FILE)
    try:
        frame = pd.read_csv(file, dtype={"method": str, "preset": str, "thin_percentiles": str},
                            keep_default_na=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError,
            ValueError) as error:
        raise ResultsFileError(f"{file}: not a readable CSV file: {_one_line(error)}") from None
    for column in OPTIONAL_SUMMARY_COLUMNS:
        if column not in frame.columns:
            frame[column] = math.nan
    missing = [c for c in SUMMARY_COLUMNS if c not in frame.columns]
    if missing:
        raise ResultsFileError(f"{file}: missing column(s) {', '.join(missing)}")
    frame["preset"] = frame["preset"].fillna("")
    # An empty cell (no thin percentile) reads as NaN, and a file from before the column has
    # NaN throughout: both are filled from n_requests, of which the column is a function.
    frame["thin_percentiles"] = [
        text if isinstance(text, str) else thin_percentiles_text(int(n)) if pd.notna(n) else ""
        for text, n in zip(frame["thin_percentiles"], frame["n_requests"], strict=True)
    ]
    return frame

