"""Load YAFS results files into pandas with the times YAFS users usually derive by hand."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import pandas as pd

from yafs_safetail.yafs.errors import YAFSInputError
from yafs_safetail.yafs.metrics import EVENT_COLUMNS, LINK_COLUMNS

DEFAULT_PERCENTILES = (50.0, 90.0, 95.0, 99.0)


@dataclass(frozen=True)
class Results:
    """The two results tables plus one row per request.

    Attributes:
        events: ``<path>.csv`` with added columns ``latency`` (network time of the message,
            ``time_reception - time_emit``), ``wait`` (queueing at the replica,
            ``time_in - time_reception``), ``service_time`` (``time_out - time_in``) and
            ``response`` (``time_out - time_emit``).
        links: ``<path>_link.csv`` as written.
        requests: one row per request ``id``: ``time_emit`` (earliest emission),
            ``first_reply`` (earliest sink arrival, NaN if none), ``response_time``
            (``first_reply - time_emit``), ``sink_rows`` and ``module_rows``.
    """

    events: pd.DataFrame
    links: pd.DataFrame
    requests: pd.DataFrame

    def percentiles(self, column: str = "response_time",
                    q: Sequence[float] = DEFAULT_PERCENTILES) -> pd.Series:
        """Percentiles (``q`` in percent) of a column of :attr:`requests` (NaN rows dropped)."""
        values = self.requests[column].dropna()
        return pd.Series([values.quantile(p / 100.0) for p in q],
                         index=[f"p{p:g}" for p in q], name=column)


def _read(path: str, columns: Sequence[str]) -> pd.DataFrame:
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise YAFSInputError(path, "", "", "results file not found") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise YAFSInputError(path, "", "", f"not a YAFS results CSV ({exc})") from None
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise YAFSInputError(path, "header", missing[0], "missing results column")
    return frame


def load_results(path: str | os.PathLike[str]) -> Results:
    """Load ``<path>.csv`` and ``<path>_link.csv`` (``path`` without extension).

    Raises:
        YAFSInputError: a file is missing, unreadable or lacks a YAFS column.
    """
    base = os.fspath(path)
    if base.endswith(".csv"):
        base = base[: -len(".csv")]
    events = _read(f"{base}.csv", EVENT_COLUMNS)
    links = _read(f"{base}_link.csv", LINK_COLUMNS)
    events["latency"] = events["time_reception"] - events["time_emit"]
    events["wait"] = events["time_in"] - events["time_reception"]
    events["service_time"] = events["time_out"] - events["time_in"]
    events["response"] = events["time_out"] - events["time_emit"]

    ids = events["id"]
    is_sink = events["type"] == "SINK_M"
    sinks = events[is_sink].groupby("id")["time_reception"].min()
    requests = pd.DataFrame({
        "time_emit": events.groupby("id", sort=True)["time_emit"].min(),
        "module_rows": (events["type"] == "COMP_M").groupby(ids).sum().astype(int),
        "sink_rows": is_sink.groupby(ids).sum().astype(int),
    })
    requests["first_reply"] = sinks.reindex(requests.index)
    requests["response_time"] = requests["first_reply"] - requests["time_emit"]
    return Results(events=events, links=links, requests=requests)
