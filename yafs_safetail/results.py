"""The results folder: its file schemas, readers, writers, summaries, ratios and reports.

This module is the single source of truth for the results folder contract described in
``docs/results.md``. It works from results files (or DataFrames with their columns) alone, so
it depends on nothing else in the package.

Conventions used everywhere here:

* Percentiles use numpy's default (``method="linear"``) interpolation.
* Summaries, ratios and the latency figures use the **test** phase only.
* A *speed-up of A over B* is ``latency(B) / latency(A)``: > 1 means A is faster. The paper's
  "Oracle ... 1.08x faster than SafeTail" is Oracle's speed-up over SafeTail, i.e.
  ``SafeTail latency / Oracle latency``; "SafeTail 1.72x faster than Rand-1" is
  ``Rand-1 latency / SafeTail latency``.
* Every file is written to a temporary name in the same folder and then renamed, and floats
  are written as their shortest round-trip repr, so the same data always gives byte-identical
  files and reading a file back gives exactly the numbers that were written.
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from yafs_safetail import paper_results
from yafs_safetail.paper_results import PERCENTILE_NAMES, paper_speedup, paper_statement

REQUESTS_FILE = "requests.csv"
RUN_FILE = "run.json"
SUMMARY_CSV_FILE = "summary.csv"
SUMMARY_MD_FILE = "summary.md"

SAFETAIL = "SafeTail"
ORACLE = "Oracle"
BASELINE_FAMILIES: tuple[str, ...] = ("Rand", "MinLoad", "MinProp")
PHASES: tuple[str, ...] = ("train", "test")
PERCENTILES: tuple[int, ...] = (50, 90, 95, 99)

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
)
#: Summary columns added after the first release: a summary.csv written before them reads with
#: NaN there.
OPTIONAL_SUMMARY_COLUMNS: tuple[str, ...] = ("min_window_n_selected", "max_window_n_selected")

# Floats are written as Python's shortest round-trip repr: deterministic (identical data gives
# identical bytes) and lossless, so a summary recomputed from requests.csv equals the one
# computed in memory before writing it, to the last bit.
FLOAT_FORMAT = None
NA_REP = "NaN"

_BASELINE_RE = re.compile(r"^(Rand|MinLoad|MinProp)-(\d+)$")


class ResultsFileError(ValueError):
    """A results file is missing or does not follow the contract (one-line message)."""


# --------------------------------------------------------------------------------------------
# Method names


def parse_method(name: str) -> tuple[str, int | None]:
    """Split a method name into its family and redundancy level.

    Args:
        name: e.g. "SafeTail", "Oracle", "Rand-2", "MinLoad-1", "MinProp-3".

    Returns:
        ``(family, x)``: ``("Rand", 2)`` for "Rand-2"; ``(name, None)`` for methods without a
        level (SafeTail, Oracle, anything unknown).
    """
    match = _BASELINE_RE.match(name)
    if match:
        return match.group(1), int(match.group(2))
    return name, None


def method_sort_key(name: str) -> tuple[int, str, int]:
    """Sort key giving SafeTail, Oracle, Rand-x, MinLoad-x, MinProp-x (x ascending), others."""
    family, level = parse_method(name)
    if name == SAFETAIL:
        return (0, "", 0)
    if name == ORACLE:
        return (1, "", 0)
    if family in BASELINE_FAMILIES and level is not None:
        return (2 + BASELINE_FAMILIES.index(family), "", level)
    return (2 + len(BASELINE_FAMILIES), name, 0)


def sort_methods(names: Iterable[str]) -> list[str]:
    """Distinct method names in report order (see :func:`method_sort_key`)."""
    return sorted(set(names), key=method_sort_key)


def baselines_of(names: Iterable[str], family: str | None = None) -> list[str]:
    """The Rand/MinLoad/MinProp methods among ``names`` (one family if given), report order."""
    out = []
    for name in sort_methods(names):
        fam, level = parse_method(name)
        if fam in BASELINE_FAMILIES and level is not None and family in (None, fam):
            out.append(name)
    return out


# --------------------------------------------------------------------------------------------
# Atomic, deterministic writing


def file_mode() -> int:
    """Permission bits an ordinary ``open(..., "w")`` would give (temporary files get 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


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
    text_columns = [c for c, kind in REQUESTS_SCHEMA.items() if kind == "str"]
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
    for column, kind in REQUESTS_SCHEMA.items():
        values = raw[column]
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
    for column in raw.columns:
        if column not in REQUESTS_SCHEMA:
            out[column] = raw[column]
    _check_requests_values(out, file)
    return out


def _first_bad(file: Path, mask: pd.Series, column: str, frame: pd.DataFrame, what: str) -> None:
    if mask.any():
        row = int(np.flatnonzero(mask.to_numpy())[0])
        raise ResultsFileError(
            f"{file}: column {column}, line {row + 2}: {what}, got {frame[column].iloc[row]!r}"
        )


def _check_requests_values(frame: pd.DataFrame, file: Path) -> None:
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
    n_listed = frame["servers"].str.count(";") + (frame["servers"] != "")
    _first_bad(file, n_listed != frame["n_selected"], "servers", frame,
               "expected n_selected server indices joined by ';'")
    # Catches the easy sign slip (latency − target): the paper's deviation is target − achieved.
    expected = frame["target_s"] - frame["latency_s"]
    tolerance = 1e-9 * np.maximum(1.0, np.abs(frame["target_s"]))
    _first_bad(file, ~(np.abs(frame["deviation_s"] - expected) <= tolerance), "deviation_s",
               frame, "expected target_s − latency_s")


# --------------------------------------------------------------------------------------------
# run.json


@dataclass(slots=True)
class RunMetadata:
    """What ``run.json`` records about a run.

    Attributes:
        use_case: 1, 2 or 3.
        use_case_name: e.g. "object detection (YOLOv5)".
        preset: "paper" or "tuned".
        seed: the run's seed.
        n_servers: n, the number of edge servers.
        beta: β, the number of steps averaged per point of the per-episode plots.
        train_steps: SafeTail's training steps.
        test_steps: test steps per method.
        topology: the topology file used.
        methods: every method in the run.
        package_version: ``yafs_safetail.__version__``.
        command: the command line that produced the run.
        extra: any further keys, kept as they are.
    """

    use_case: int
    use_case_name: str
    preset: str
    seed: int
    n_servers: int
    beta: int
    train_steps: int
    test_steps: int
    topology: str
    methods: list[str]
    package_version: str
    command: str
    extra: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> str:
        """Deterministic JSON text (sorted keys, two-space indent, trailing newline)."""
        data = {k: v for k, v in asdict(self).items() if k != "extra"}
        data.update(self.extra)
        return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


RUN_JSON_KEYS: tuple[str, ...] = tuple(f.name for f in fields(RunMetadata) if f.name != "extra")
_RUN_INT_KEYS = ("use_case", "seed", "n_servers", "beta", "train_steps", "test_steps")


def write_run_json(directory: str | os.PathLike[str], run: RunMetadata) -> Path:
    """Write ``run.json`` into ``directory`` atomically and deterministically."""
    return write_text_atomic(Path(directory) / RUN_FILE, run.to_json())


def read_run_json(path: str | os.PathLike[str]) -> RunMetadata:
    """Read and check ``run.json`` (or the one inside a results folder).

    Raises:
        ResultsFileError: missing file, bad JSON, a missing key or a value of the wrong type.
    """
    file = _results_file(path, RUN_FILE)
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ResultsFileError(f"{file}: not valid JSON: {_one_line(error)}") from None
    if not isinstance(data, dict):
        raise ResultsFileError(f"{file}: expected a JSON object at the top level")
    missing = [k for k in RUN_JSON_KEYS if k not in data]
    if missing:
        raise ResultsFileError(f"{file}: missing key(s) {', '.join(missing)}")
    for key in _RUN_INT_KEYS:
        if not isinstance(data[key], int) or isinstance(data[key], bool):
            raise ResultsFileError(f"{file}: key {key}: expected an integer, got {data[key]!r}")
    if data["beta"] < 1:
        raise ResultsFileError(f"{file}: key beta: expected an integer >= 1, got {data['beta']!r}")
    if not isinstance(data["methods"], list) or not all(isinstance(m, str) for m in data["methods"]):
        raise ResultsFileError(f"{file}: key methods: expected a list of method names")
    known = {k: data[k] for k in RUN_JSON_KEYS}
    for key in ("use_case_name", "preset", "topology", "package_version", "command"):
        known[key] = str(known[key])
    extra = {k: v for k, v in data.items() if k not in known}
    return RunMetadata(**known, extra=extra)


# --------------------------------------------------------------------------------------------
# Summary


def _nanmean(values: np.ndarray) -> float:
    finite = values[~np.isnan(values)]
    return float(finite.mean()) if finite.size else math.nan


def _window_means(values: np.ndarray, window: int) -> np.ndarray:
    """Means of consecutive windows of ``window`` values (a shorter last window included)."""
    return np.array([values[i:i + window].mean() for i in range(0, len(values), window)])


def summarize(requests: pd.DataFrame, preset: str = "", beta: int | None = None) -> pd.DataFrame:
    """Per-method statistics of the test phase.

    Args:
        requests: a requests table (see ``REQUESTS_COLUMNS``).
        preset: written into the ``preset`` column.
        beta: β; the servers per request averaged over consecutive windows of β test steps (the
            paper's Fig. (e) points) give ``min_window_n_selected``/``max_window_n_selected``
            (NaN when None).

    Returns:
        One row per method with a test row, in report order, columns ``SUMMARY_COLUMNS``.
        Percentiles are numpy's linear interpolation; ``target_met_rate`` is the share of
        requests with latency <= target; ``mean_abs_reward`` ignores NaN rewards (NaN when the
        method records none).
    """
    _require_columns(requests, REQUESTS_COLUMNS, "requests table")
    test = requests[requests["phase"] == "test"]
    rows = []
    for method in sort_methods(test["method"]):
        part = test[test["method"] == method]
        latency = part["latency_s"].to_numpy(dtype=float)
        n_selected = part["n_selected"].to_numpy(dtype=float)
        p50, p90, p95, p99 = np.percentile(latency, PERCENTILES)
        if beta:
            in_order = part.sort_values("step", kind="stable")["n_selected"].to_numpy(dtype=float)
            windows = _window_means(in_order, beta)
        else:
            windows = np.array([math.nan])
        rows.append({
            "method": method,
            "preset": preset,
            "n_requests": len(part),
            "p50_s": p50,
            "p90_s": p90,
            "p95_s": p95,
            "p99_s": p99,
            "mean_s": latency.mean(),
            "mean_access_rate": part["access_rate"].to_numpy(dtype=float).mean(),
            "mean_n_selected": n_selected.mean(),
            "median_n_selected": float(np.median(n_selected)),
            "min_n_selected": int(n_selected.min()),
            "max_n_selected": int(n_selected.max()),
            "mean_target_s": part["target_s"].to_numpy(dtype=float).mean(),
            "mean_deviation_s": part["deviation_s"].to_numpy(dtype=float).mean(),
            "target_met_rate": float(np.mean(latency <= part["target_s"].to_numpy(dtype=float))),
            "fallback_rate": part["fallback"].to_numpy(dtype=float).mean(),
            "mean_refused": part["refused"].to_numpy(dtype=float).mean(),
            "mean_abs_reward": _nanmean(np.abs(part["reward"].to_numpy(dtype=float))),
            "min_window_n_selected": float(windows.min()),
            "max_window_n_selected": float(windows.max()),
        })
    frame = pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))
    return frame.astype({"n_requests": "int64", "min_n_selected": "int64",
                         "max_n_selected": "int64"})


def read_summary_csv(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read a ``summary.csv`` (or the one inside a results folder).

    Raises:
        ResultsFileError: missing or unreadable file, or a missing column.
    """
    file = _results_file(path, SUMMARY_CSV_FILE)
    try:
        frame = pd.read_csv(file, dtype={"method": str, "preset": str}, keep_default_na=True)
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
    return frame


# --------------------------------------------------------------------------------------------
# Speed-ups and the paper's claims


def _latency(summary: pd.DataFrame, method: str, percentile: int) -> float:
    row = summary[summary["method"] == method]
    if row.empty:
        return math.nan
    return float(row[f"p{percentile}_s"].iloc[0])


def speedup(summary: pd.DataFrame, method: str, reference: str, percentile: int) -> float:
    """Speed-up of ``method`` over ``reference`` at a percentile: ``latency(ref) / latency(method)``.

    Returns NaN when either method is absent from ``summary``.
    """
    mine = _latency(summary, method, percentile)
    theirs = _latency(summary, reference, percentile)
    if math.isnan(mine) or math.isnan(theirs) or mine <= 0:
        return math.nan
    return theirs / mine


SPEEDUP_COLUMNS: tuple[str, ...] = (
    "method", "reference", "percentile", "ours", "paper", "stated",
)


def speedup_table(summary: pd.DataFrame, use_case: int | None) -> pd.DataFrame:
    """The ratios the paper quotes, ours next to the paper's.

    Rows: Oracle over SafeTail at each percentile (``ours`` = SafeTail latency / Oracle
    latency, the paper's "Oracle ... 1.08x faster"), then SafeTail over each Rand/MinLoad/
    MinProp baseline present at each percentile (``ours`` = baseline latency / SafeTail
    latency). ``paper`` is the paper's number in the same direction (converted when the paper
    states the reciprocal; NaN where it states none) and ``stated`` its wording.

    Args:
        summary: from :func:`summarize`.
        use_case: 1, 2 or 3 to fill the paper columns; None leaves them empty.

    Returns:
        A DataFrame with columns ``SPEEDUP_COLUMNS``; empty when SafeTail is absent.
    """
    methods = list(summary["method"])
    pairs: list[tuple[str, str]] = []
    if SAFETAIL in methods:
        if ORACLE in methods:
            pairs.append((ORACLE, SAFETAIL))
        pairs.extend((SAFETAIL, baseline) for baseline in baselines_of(methods))
    rows = []
    for method, reference in pairs:
        for percentile in PERCENTILES:
            paper = None if use_case is None else paper_speedup(use_case, method, reference,
                                                                 percentile)
            stated = None if use_case is None else paper_statement(use_case, method, reference,
                                                                   percentile)
            rows.append({
                "method": method,
                "reference": reference,
                "percentile": percentile,
                "ours": speedup(summary, method, reference, percentile),
                "paper": math.nan if paper is None else paper,
                "stated": stated or "",
            })
    return pd.DataFrame(rows, columns=list(SPEEDUP_COLUMNS))


def _claim_holds(key: str, summary: pd.DataFrame) -> bool | None:
    methods = list(summary["method"])
    if SAFETAIL not in methods:
        return None
    safetail = summary[summary["method"] == SAFETAIL].iloc[0]
    target = float(safetail["mean_target_s"])
    baselines = baselines_of(methods)
    if key == "below_target_all":
        return all(float(safetail[f"p{p}_s"]) < target for p in PERCENTILES)
    if key == "median_below_target":
        return float(safetail["p50_s"]) < target
    if key == "servers_1_to_3":
        low, high = float(safetail["min_window_n_selected"]), float(safetail["max_window_n_selected"])
        if math.isnan(low):  # a summary without β windows: every request on its own
            low, high = float(safetail["min_n_selected"]), float(safetail["max_n_selected"])
        return low >= 1 and high <= 3
    if key == "mean_servers_2_to_3":
        return 2.0 <= float(safetail["mean_n_selected"]) <= 3.0
    if key == "mostly_1_to_2_servers":
        return float(safetail["median_n_selected"]) <= 2.0
    if key == "oracle_tail_above_target":
        if ORACLE not in methods:
            return None
        oracle = summary[summary["method"] == ORACLE].iloc[0]
        return float(oracle["p99_s"]) > float(oracle["mean_target_s"])
    if key == "beats_x23_all":
        higher = [b for b in baselines if parse_method(b)[1] in (2, 3)]
        if not higher:
            return None
        return all(speedup(summary, SAFETAIL, b, p) > 1 for b in higher for p in PERCENTILES)
    if key == "baseline_better_p50_p90":
        if not baselines:
            return None
        return all(any(speedup(summary, SAFETAIL, b, p) < 1 for b in baselines) for p in (50, 90))
    if key == "safetail_better_p95_p99":
        if not baselines:
            return None
        return all(speedup(summary, SAFETAIL, b, p) > 1 for b in baselines for p in (95, 99))
    raise KeyError(f"no check for paper claim {key!r}")


def check_claims(summary: pd.DataFrame, use_case: int) -> pd.DataFrame:
    """The paper's qualitative statements for ``use_case`` and whether this run bears them out.

    Returns:
        Columns ``key, text, holds`` with ``holds`` True, False or None (cannot be checked:
        a needed method is absent).
    """
    claims = [c for c in paper_results.PAPER_CLAIMS if c.use_case == use_case]
    return pd.DataFrame({
        "key": pd.Series([c.key for c in claims], dtype=object),
        "text": pd.Series([c.text for c in claims], dtype=object),
        # object dtype keeps True/False/None as they are (no coercion to numpy bools or NaN).
        "holds": pd.Series([_claim_holds(c.key, summary) for c in claims], dtype=object),
    })


# --------------------------------------------------------------------------------------------
# Markdown


def _fmt(value: float, digits: int = 3) -> str:
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else (
        f"{value:.{digits}f}"
    )


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(row) + " |" for row in rows)
    return lines


def _speedup_lines(table: pd.DataFrame, method: str, reference: str | None) -> list[str]:
    header = ["comparison"]
    for percentile in PERCENTILES:
        name = PERCENTILE_NAMES[percentile]
        header += [f"{name} ours", f"{name} paper"]
    rows = []
    pairs = table[["method", "reference"]].drop_duplicates().itertuples(index=False)
    for pair_method, pair_reference in pairs:
        if pair_method != method or (reference is not None and pair_reference != reference):
            continue
        part = table[(table["method"] == pair_method) & (table["reference"] == pair_reference)]
        row = [f"{pair_method} over {pair_reference}"]
        for percentile in PERCENTILES:
            entry = part[part["percentile"] == percentile].iloc[0]
            row += [_fmt(entry["ours"], 2), _fmt(entry["paper"], 2)]
        rows.append(row)
    return _table(header, rows) if rows else []


def _stated_lines(table: pd.DataFrame) -> list[str]:
    statements = sorted({s for s in table["stated"] if s})
    return [f"- {s}" for s in statements]


def summary_markdown(summary: pd.DataFrame, run: RunMetadata | None = None) -> str:
    """The run's markdown report: latency table, the paper's ratios, the paper's claims.

    Args:
        summary: from :func:`summarize`.
        run: the run's metadata (names the use case, preset and seed; enables paper columns).

    Returns:
        Markdown text ending with a newline.
    """
    use_case = run.use_case if run else None
    if run:
        title = (f"# SafeTail results: use case {run.use_case} ({run.use_case_name}), "
                 f"preset `{run.preset}`, seed {run.seed}")
    else:
        title = "# SafeTail results (no run.json: use case, preset and seed unknown)"
    lines = [title, ""]
    if use_case is not None and SAFETAIL in set(summary["method"]):
        from yafs_safetail.fidelity import run_line  # fidelity reads this module's tables

        lines += [run_line(summary, use_case), ""]
    n_test = ", ".join(f"{m} {n}" for m, n in zip(summary["method"], summary["n_requests"],
                                                   strict=True))
    lines += [
        "Test phase only. Latencies in seconds; percentiles by numpy's linear interpolation. "
        f"Test requests per method: {n_test or 'none'}.",
        "",
    ]
    rows = [
        [m, _fmt(r.p50_s), _fmt(r.p90_s), _fmt(r.p95_s), _fmt(r.p99_s),
         _fmt(r.mean_access_rate), _fmt(r.mean_n_selected, 2), _fmt(r.mean_target_s),
         _fmt(r.target_met_rate), _fmt(r.fallback_rate)]
        for m, r in zip(summary["method"], summary.itertuples(index=False), strict=True)
    ]
    lines += _table(
        ["method", "median", "p90", "p95", "p99", "mean access rate", "mean servers",
         "mean target", "target met", "fallback rate"],
        rows,
    )
    table = speedup_table(summary, use_case)
    lines += ["", "## Oracle vs SafeTail", ""]
    oracle_lines = _speedup_lines(table, ORACLE, SAFETAIL)
    if oracle_lines:
        lines += [
            "Oracle's speed-up over SafeTail = SafeTail latency / Oracle latency "
            "(> 1: Oracle faster). \"ours\" is this run; \"paper\" is the paper's stated number "
            "in the same direction (— where the paper states none; where it states SafeTail's "
            "speed-up over Oracle instead, the column shows the reciprocal).",
            "",
            *oracle_lines,
        ]
    else:
        lines.append("Not available: the run lacks SafeTail or Oracle test rows.")
    lines += ["", "## SafeTail vs baselines", ""]
    baseline_lines = _speedup_lines(table, SAFETAIL, None)
    if baseline_lines:
        lines += [
            "SafeTail's speed-up over a baseline = baseline latency / SafeTail latency "
            "(> 1: SafeTail faster). \"ours\" is this run; \"paper\" is the paper's stated "
            "number (— where the paper states none).",
            "",
            *baseline_lines,
        ]
    else:
        lines.append("Not available: the run lacks SafeTail or baseline test rows.")
    stated = _stated_lines(table)
    if stated:
        lines += ["", "The paper's statements behind the \"paper\" columns (facts.md):", "",
                  *stated]
    if use_case is not None:
        claims = check_claims(summary, use_case)
        if not claims.empty:
            lines += ["", "## The paper's qualitative statements", "",
                      "Where the paper is vague, our reading is written into the statement "
                      "(test phase; target = the average target latency).", ""]
            verdict = {True: "yes", False: "no", None: "cannot check"}
            lines += _table(["paper says", "holds in this run"],
                            [[t, verdict[h]] for t, h in zip(claims["text"], claims["holds"],
                                                             strict=True)])
    return "\n".join(lines) + "\n"


def write_summary(
    directory: str | os.PathLike[str],
    requests: pd.DataFrame | None = None,
    run: RunMetadata | None = None,
) -> pd.DataFrame:
    """Write ``summary.csv`` and ``summary.md`` into a results folder.

    Args:
        directory: the results folder.
        requests: the requests table; read from ``requests.csv`` when None.
        run: the run's metadata; read from ``run.json`` when None and the file exists.

    Returns:
        The summary DataFrame that was written.
    """
    folder = Path(directory)
    if requests is None:
        requests = read_requests_csv(folder)
    if run is None and (folder / RUN_FILE).is_file():
        run = read_run_json(folder)
    summary = summarize(requests, preset=run.preset if run else "", beta=run.beta if run else None)
    write_text_atomic(folder / SUMMARY_CSV_FILE, _csv_text(summary))
    write_text_atomic(folder / SUMMARY_MD_FILE, summary_markdown(summary, run))
    return summary


def write_results(
    directory: str | os.PathLike[str], requests: pd.DataFrame, run: RunMetadata
) -> pd.DataFrame:
    """Write a run's ``requests.csv``, ``run.json``, ``summary.csv`` and ``summary.md``.

    Args:
        directory: the results folder (must exist).
        requests: the requests table.
        run: the run's metadata.

    Returns:
        The summary DataFrame.
    """
    write_requests_csv(requests, directory)
    write_run_json(directory, run)
    return write_summary(directory, requests, run)


# --------------------------------------------------------------------------------------------
# β-step averages (Figs. 5-7 (e)-(g))

BETA_COLUMNS: tuple[str, ...] = ("phase", "block", "avg_episode", "value", "n_steps")


def _ordered_rows(requests: pd.DataFrame, method: str, phase: str) -> pd.DataFrame:
    part = requests[(requests["method"] == method) & (requests["phase"] == phase)]
    return part.sort_values("step", kind="stable")


def beta_averages(
    requests: pd.DataFrame,
    beta: int,
    column: str,
    *,
    method: str = SAFETAIL,
    absolute: bool = False,
) -> pd.DataFrame:
    """Averages of ``column`` over consecutive blocks of β steps, as the paper plots them.

    The method's training rows come first, then its test rows, each in step order; blocks
    never straddle the two phases (a phase whose length is not a multiple of β ends in a
    shorter block). A block's ``avg_episode`` is the number of steps up to its end divided by
    β, counting the training steps before the test ones, so full blocks sit at 1, 2, 3, ...
    NaN values (e.g. missing rewards) are left out of a block's mean.

    Args:
        requests: a requests table.
        beta: β, steps per plotted point.
        column: e.g. "access_rate", "deviation_s", "reward".
        method: whose rows to average.
        absolute: average ``|column|`` (for the |reward| plot).

    Returns:
        Columns ``BETA_COLUMNS``: phase, block index within the phase, average episode number,
        the block mean and the block length.
    """
    if beta < 1:
        raise ValueError(f"beta must be >= 1, got {beta}")
    rows = []
    offset = 0
    for phase in PHASES:
        values = _ordered_rows(requests, method, phase)[column].to_numpy(dtype=float)
        if absolute:
            values = np.abs(values)
        for block, start in enumerate(range(0, len(values), beta)):
            chunk = values[start : start + beta]
            rows.append({
                "phase": phase,
                "block": block,
                "avg_episode": (offset + start + len(chunk)) / beta,
                "value": _nanmean(chunk),
                "n_steps": len(chunk),
            })
        offset += len(values)
    return pd.DataFrame(rows, columns=list(BETA_COLUMNS))


def access_rate_by_episode(requests: pd.DataFrame, beta: int) -> pd.DataFrame:
    """SafeTail's β-step average access rate (Fig. (e))."""
    return beta_averages(requests, beta, "access_rate")


def latency_deviation_by_episode(requests: pd.DataFrame, beta: int) -> pd.DataFrame:
    """SafeTail's β-step average latency deviation, target − latency (Fig. (f))."""
    return beta_averages(requests, beta, "deviation_s")


def abs_reward_by_episode(requests: pd.DataFrame, beta: int) -> pd.DataFrame:
    """SafeTail's β-step average of |reward| (Fig. (g))."""
    return beta_averages(requests, beta, "reward", absolute=True)


def train_test_boundary(requests: pd.DataFrame, beta: int, method: str = SAFETAIL) -> float:
    """The average episode number where the method's training ends and testing starts."""
    n_train = int(((requests["method"] == method) & (requests["phase"] == "train")).sum())
    return n_train / beta


# --------------------------------------------------------------------------------------------
# Across seeds


def geometric_interval(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Geometric mean of positive values (e.g. ratios over seeds) and a Student-t interval on the
    log scale, which never leaves (0, ∞).

    Returns:
        ``(geometric mean, low, high)``; NaN interval with fewer than two values; all NaN when
        no value is finite and positive.
    """
    from scipy import stats

    data = np.asarray([v for v in values if math.isfinite(v) and v > 0], dtype=float)
    if data.size == 0:
        return math.nan, math.nan, math.nan
    logs = np.log(data)
    centre = float(logs.mean())
    if data.size < 2:
        return math.exp(centre), math.nan, math.nan
    half = float(stats.t.ppf((1 + level) / 2, data.size - 1)) * float(logs.std(ddof=1))
    half /= math.sqrt(data.size)
    return math.exp(centre), math.exp(centre - half), math.exp(centre + half)


#: Resamples of :func:`bootstrap_interval` (seeded: the same values give the same interval).
BOOTSTRAP_RESAMPLES = 10_000


def bootstrap_interval(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean over seeds and a percentile-bootstrap interval of it (SciPy), which never leaves the
    range of the values, so a latency or a rate never gets an impossible bound.

    Returns:
        ``(mean, low, high)``; NaN interval with fewer than two values or when they are all
        equal (the interval is then the value itself).
    """
    from scipy import stats

    data = np.asarray([v for v in values if not math.isnan(v)], dtype=float)
    if data.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(data.mean())
    if data.size < 2:
        return mean, math.nan, math.nan
    if np.all(data == data[0]):
        return mean, mean, mean
    result = stats.bootstrap((data,), np.mean, confidence_level=level, method="percentile",
                             n_resamples=BOOTSTRAP_RESAMPLES, rng=np.random.default_rng(0))
    return mean, float(result.confidence_interval.low), float(result.confidence_interval.high)


def _summary_of_run(folder: Path) -> pd.DataFrame:
    if (folder / SUMMARY_CSV_FILE).is_file():
        return read_summary_csv(folder)
    return summarize(read_requests_csv(folder), beta=read_run_json(folder).beta)


def _load_runs(directories: Sequence[str | os.PathLike[str]]) -> list[tuple[RunMetadata, pd.DataFrame]]:
    if not directories:
        raise ValueError("no run folders given")
    runs = []
    for directory in directories:
        folder = Path(directory)
        if not folder.is_dir():
            raise ResultsFileError(f"{folder}: results folder not found")
        runs.append((read_run_json(folder), _summary_of_run(folder)))
    use_cases = {run.use_case for run, _ in runs}
    if len(use_cases) > 1:
        raise ResultsFileError(
            f"{Path(directories[0]) / RUN_FILE}: key use_case: runs mix use cases "
            f"{sorted(use_cases)}"
        )
    return runs


AGGREGATE_METRICS: tuple[str, ...] = (
    "p50_s", "p90_s", "p95_s", "p99_s", "mean_s", "mean_access_rate", "mean_target_s",
)


def aggregate_summaries(directories: Sequence[str | os.PathLike[str]]) -> pd.DataFrame:
    """Per method and metric, the mean over seeds and a 95% percentile-bootstrap interval.

    Args:
        directories: run folders of one use case (one per seed), each with ``run.json`` and
            ``summary.csv`` (or ``requests.csv``, summarised on the fly).

    Returns:
        Columns ``method, metric, mean, ci_low, ci_high, n_seeds`` (metrics from
        ``AGGREGATE_METRICS``); methods in report order.

    Raises:
        ResultsFileError: a folder or file is missing or bad, or the runs mix use cases.
    """
    runs = _load_runs(directories)
    methods = sort_methods(m for _, summary in runs for m in summary["method"])
    rows = []
    for method in methods:
        for metric in AGGREGATE_METRICS:
            values = []
            for _, summary in runs:
                part = summary[summary["method"] == method]
                if not part.empty:
                    values.append(float(part[metric].iloc[0]))
            mean, low, high = bootstrap_interval(values)
            rows.append({"method": method, "metric": metric, "mean": mean, "ci_low": low,
                         "ci_high": high, "n_seeds": len(values)})
    return pd.DataFrame(rows, columns=["method", "metric", "mean", "ci_low", "ci_high", "n_seeds"])


def aggregate_markdown(stats: pd.DataFrame, digits: int = 3) -> str:
    """Markdown table of :func:`aggregate_summaries`: one row per method, ``mean [95% interval]``.

    Args:
        stats: from :func:`aggregate_summaries`.
        digits: decimals shown.

    Returns:
        Markdown text ending with a newline.
    """
    header = ["method", "seeds", *[PERCENTILE_NAMES[p] + " (s)" for p in PERCENTILES],
              "mean access rate", "mean target (s)"]
    metrics = [f"p{p}_s" for p in PERCENTILES] + ["mean_access_rate", "mean_target_s"]
    rows = []
    for method in sort_methods(stats["method"]):
        part = stats[stats["method"] == method].set_index("metric")
        row = [method, str(int(part["n_seeds"].max()))]
        for metric in metrics:
            cell = _fmt(part.loc[metric, "mean"], digits)
            if not math.isnan(part.loc[metric, "ci_low"]):
                cell += (f" [{part.loc[metric, 'ci_low']:.{digits}f}, "
                         f"{part.loc[metric, 'ci_high']:.{digits}f}]")
            row.append(cell)
        rows.append(row)
    lines = ["Test phase; mean over seeds [95% bootstrap interval over seeds].", "",
             *_table(header, rows)]
    return "\n".join(lines) + "\n"


AGREE_TOLERANCE = 0.05
UNITY_TOLERANCE = 0.02


def _difference_note(mean: float, low: float, high: float, paper: float, method: str,
                     reference: str) -> str:
    if math.isnan(paper):
        return "paper states no number"
    if math.isnan(mean):
        return "not measured in these runs"
    if not math.isnan(low):
        if low <= paper <= high:
            return "consistent: paper value inside our 95% interval"
    elif abs(mean / paper - 1) <= AGREE_TOLERANCE:
        return f"close: within {AGREE_TOLERANCE:.0%} (single seed, no interval)"

    def side(value: float) -> int:
        return 0 if abs(value - 1) <= UNITY_TOLERANCE else (1 if value > 1 else -1)

    if side(mean) == side(paper):
        return f"differs in size: ours {mean:.2f} vs paper {paper:.2f}"
    faster = {1: f"{method} faster", -1: f"{reference} faster", 0: "about equal"}
    return f"differs in direction: ours {faster[side(mean)]}, paper {faster[side(paper)]}"


AGGREGATE_SPEEDUP_COLUMNS: tuple[str, ...] = (
    "use_case", "method", "reference", "percentile", "mean", "ci_low", "ci_high", "n_seeds",
    "paper", "stated", "note",
)


def aggregate_speedups(directories: Sequence[str | os.PathLike[str]]) -> pd.DataFrame:
    """The paper's ratios (see :func:`speedup_table`) per seed, then their geometric mean and a
    95% t-interval on the log scale (:func:`geometric_interval`).

    The ratio is computed within each seed first and then combined, so the interval reflects
    the seed-to-seed spread of the ratio itself. ``note`` compares with the paper: inside our
    interval ("consistent"; a wide interval makes this weak, so read it with the interval);
    with one seed, within 5% ("close"); otherwise "differs in size" when both sit on the same
    side of 1 (±2% counts as equal) and "differs in direction" when not.

    Args:
        directories: run folders of one use case, one per seed.

    Returns:
        Columns ``AGGREGATE_SPEEDUP_COLUMNS``.
    """
    runs = _load_runs(directories)
    use_case = runs[0][0].use_case
    tables = [speedup_table(summary, use_case) for _, summary in runs]
    keys = pd.concat(tables)[["method", "reference", "percentile", "paper", "stated"]]
    keys = keys.drop_duplicates(["method", "reference", "percentile"])
    rows = []
    for entry in keys.itertuples(index=False):
        values = []
        for table in tables:
            match = table[(table["method"] == entry.method) & (table["reference"] == entry.reference)
                          & (table["percentile"] == entry.percentile)]
            if not match.empty:
                values.append(float(match["ours"].iloc[0]))
        mean, low, high = geometric_interval(values)
        rows.append({
            "use_case": use_case, "method": entry.method, "reference": entry.reference,
            "percentile": entry.percentile, "mean": mean, "ci_low": low, "ci_high": high,
            "n_seeds": len([v for v in values if not math.isnan(v)]), "paper": entry.paper,
            "stated": entry.stated,
            "note": _difference_note(mean, low, high, entry.paper, entry.method, entry.reference),
        })
    return pd.DataFrame(rows, columns=list(AGGREGATE_SPEEDUP_COLUMNS))


def comparison_markdown(aggregated: pd.DataFrame, only_stated: bool = False) -> str:
    """Side-by-side markdown table of our ratios (mean [95% interval]) and the paper's.

    Args:
        aggregated: from :func:`aggregate_speedups` (several use cases may be concatenated).
        only_stated: keep only the rows for which the paper states a number.

    Returns:
        Markdown text ending with a newline.
    """
    rows = []
    for entry in aggregated.itertuples(index=False):
        if only_stated and math.isnan(entry.paper):
            continue
        ours = _fmt(entry.mean, 2)
        if not math.isnan(entry.ci_low):
            ours += f" [{entry.ci_low:.2f}, {entry.ci_high:.2f}]"
        rows.append([
            str(entry.use_case), f"{entry.method} over {entry.reference}",
            PERCENTILE_NAMES[int(entry.percentile)], ours, str(entry.n_seeds),
            _fmt(entry.paper, 2), entry.note,
        ])
    lines = [
        "Speed-up of A over B = latency(B) / latency(A) (> 1: A faster). \"ours\" = geometric mean over "
        "seeds [95% t-interval on the log scale]; \"paper\" = the paper's stated number in the same "
        "direction (facts.md).",
        "",
        *_table(["use case", "comparison", "percentile", "ours", "seeds", "paper", "differs?"],
                rows),
    ]
    return "\n".join(lines) + "\n"
