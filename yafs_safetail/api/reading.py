"""The API's reading half: a results folder read and checked (:class:`RunResults`), and
methods compared over seeds. Light to import: pandas loads on the first call."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from yafs_safetail.api.running import ApiError

if TYPE_CHECKING:
    import pandas as pd

    from yafs_safetail.results.run_json import RunMetadata


@dataclass(frozen=True)
class RunResults:
    """One results folder, read and checked.

    Attributes:
        folder: the results folder.
        summary: ``summary.csv``: one row per method (test phase): ``p50_s``, ``p90_s``,
            ``p95_s``, ``p99_s``, ``mean_s``, ``mean_access_rate``, ``target_met_rate``...
            (docs/results.md lists every column).
        requests: ``requests.csv``: one row per request, method and phase (``latency_s``,
            ``target_s``, ``servers``, ``reward``...).
        run: ``run.json``: use case, preset, seed, β, steps, methods, the world's settings.
    """

    folder: Path
    summary: pd.DataFrame
    requests: pd.DataFrame
    run: RunMetadata

    @property
    def test_requests(self) -> pd.DataFrame:
        """The test phase's rows, the ones every method is compared on (same requests)."""
        return self.requests[self.requests["phase"] == "test"]


def read_results(folder: str | os.PathLike[str]) -> RunResults:
    """Read a results folder written by :func:`run` or ``yafs-safetail run``.

    Raises:
        ValueError: the folder, ``summary.csv``, ``requests.csv`` or ``run.json`` is missing or
            bad (one line naming the file and the field).
    """
    from yafs_safetail import results

    path = Path(folder)
    if not path.is_dir():
        raise results.ResultsFileError(f"{path}: results folder not found")
    return RunResults(folder=path, summary=results.read_summary_csv(path),
                      requests=results.read_requests_csv(path), run=results.read_run_json(path))


def as_results(results: RunResults | str | os.PathLike[str]) -> RunResults:
    return results if isinstance(results, RunResults) else read_results(results)


#: The summary columns :func:`compare_over_seeds` reports by default.
COMPARED_METRICS: tuple[str, ...] = ("p50_s", "p95_s", "p99_s", "mean_access_rate")


def compare_over_seeds(folders: Sequence[str | os.PathLike[str]], methods: Sequence[str] | None = None,
                       metrics: Sequence[str] = COMPARED_METRICS) -> pd.DataFrame:
    """Methods compared over runs of one use case (one run per seed): the mean over seeds and
    its 95% percentile-bootstrap interval (``results.over_seeds.bootstrap_interval``).

    Args:
        folders: results folders of one use case, one per seed.
        methods: the methods to keep, in this order (default: every method, report order).
        metrics: summary columns (``results.over_seeds.AGGREGATE_METRICS``).

    Returns:
        One row per method: for each metric ``<metric>``, ``<metric>_low`` and
        ``<metric>_high``, then ``n_seeds`` (the runs that have the method).

    Raises:
        ValueError: no folders, bad results files, runs mixing use cases, or an unknown method
            or metric.
    """
    from yafs_safetail.results.over_seeds import AGGREGATE_METRICS, aggregate_summaries

    bad_metric = [m for m in metrics if m not in AGGREGATE_METRICS]
    if bad_metric or not metrics:
        raise ApiError(f"compare_over_seeds(): metrics: {bad_metric[0] if bad_metric else 'none given'!r}; "
                       f"expected some of {', '.join(AGGREGATE_METRICS)}")
    if not folders:
        raise ApiError("compare_over_seeds(): folders: none given")
    table = aggregate_summaries(folders)
    present = list(dict.fromkeys(table["method"]))
    chosen = present if methods is None else list(methods)
    missing = [m for m in chosen if m not in present]
    if missing:
        raise ApiError(f"compare_over_seeds(): methods: {missing[0]!r} is in none of the runs; they "
                       f"have {', '.join(present)}")
    import pandas as pd

    rows = []
    for method in chosen:
        part = table[table["method"] == method].set_index("metric")
        row: dict[str, Any] = {"method": method}
        for metric in metrics:
            row[metric] = part.at[metric, "mean"]
            row[f"{metric}_low"] = part.at[metric, "ci_low"]
            row[f"{metric}_high"] = part.at[metric, "ci_high"]
        row["n_seeds"] = int(part["n_seeds"].max())
        rows.append(row)
    return pd.DataFrame(rows)
