"""YAFS's ``stats.Stats``: summaries read back from the results CSVs.

The methods YAFS3 has return what YAFS3's return (``count_messages`` counts link rows,
``messages_not_transmitted`` is the last ``buffer`` value as a one-row Series, ...); where
YAFS3's code fails on current pandas or references a method it lacks, the method here does
what YAFS3's evidently meant (noted on each). ``loop_latencies`` is an addition.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from yafs_safetail.yafs.analysis import load_results
from yafs_safetail.yafs.metrics import Metrics


class Stats:
    """Read ``<defaultPath>.csv`` and ``<defaultPath>_link.csv`` and summarise them.

    Attributes:
        df: the module/sink rows (YAFS's derived ``time_*`` columns are added on first use).
        df_link: the link rows.

    Raises:
        YAFSInputError: a results file is missing, unreadable or lacks a YAFS column.
    """

    def __init__(self, defaultPath: str = "result") -> None:  # noqa: N803 - YAFS name
        results = load_results(defaultPath)
        self.df_link = results.links
        self.df = results.events.drop(columns=["latency", "wait", "service_time", "response"])

    # ----------------------------------------------------------------- YAFS3's methods

    def bytes_transmitted(self) -> Any:
        """Bytes summed over every hop (link rows)."""
        return self.df_link["size"].sum()

    def count_messages(self) -> int:
        """Number of hops (link rows), as YAFS3 counts "messages"."""
        return len(self.df_link)

    def utilization(self, id_entity: Any, total_time: float, from_time: float = 0.0) -> float:
        """Busy time of process ``id_entity`` (a ``DES.dst``) over ``total_time`` (YAFS3
        ignores ``from_time``; so does this)."""
        if "time_service" not in self.df.columns:
            self.df["time_service"] = self.df.time_out - self.df.time_in
        values = self.df.groupby("DES.dst").time_service.agg("sum")
        return values[id_entity] / total_time

    def compute_times_df(self) -> None:
        """Add YAFS's time columns to :attr:`df`."""
        df = self.df
        df[Metrics.TIME_LATENCY] = df["time_reception"] - df["time_emit"]
        df[Metrics.TIME_WAIT] = df["time_in"] - df["time_reception"]
        df[Metrics.TIME_SERVICE] = df["time_out"] - df["time_in"]
        df[Metrics.TIME_RESPONSE] = df["time_out"] - df["time_reception"]
        df[Metrics.TIME_TOTAL_RESPONSE] = df[Metrics.TIME_RESPONSE] + df[Metrics.TIME_LATENCY]

    def times(self, time: str, value: str = "mean") -> pd.DataFrame:
        """``time`` column aggregated by message name."""
        if Metrics.TIME_RESPONSE not in self.df.columns:
            self.compute_times_df()
        return self.df.groupby("message").agg({time: value})

    def average_loop_response(self, time_loops: Sequence[Sequence[str]]) -> list[float]:
        """Per loop (a list of message names), the sum of each message's mean total response
        time; a message with no row adds 0. (YAFS3 indexes the mean positionally with
        ``[0]``, which current pandas refuses; the value is the same.)"""
        if Metrics.TIME_RESPONSE not in self.df.columns:
            self.compute_times_df()
        means = self.df.groupby("message")[Metrics.TIME_TOTAL_RESPONSE].mean()
        return [float(sum(means.get(msg, 0.0) for msg in loop)) for loop in time_loops]

    def get_watt(self, totaltime: float, topology: Any, by: str = Metrics.WATT_SERVICE) -> dict[Any, dict[str, Any]]:
        """Energy per node from the entities' ``WATT`` (and ``model``, ``type``) attributes.

        ``by=WATT_SERVICE``: service time on the node times ``WATT``, for nodes that served.
        ``by=WATT_UPTIME``: uptime (``uptime`` attribute ``(start, end)``, ``end`` None =
        ``totaltime``) times ``WATT``, for every entity. Missing ``type`` reads as None.
        """
        results: dict[Any, dict[str, Any]] = {}
        info = topology.get_info()
        if by == Metrics.WATT_SERVICE:
            if Metrics.TIME_RESPONSE not in self.df.columns:
                self.compute_times_df()
            nodes = self.df.groupby("TOPO.dst").agg({Metrics.TIME_SERVICE: "sum"})
            for node in nodes.index:
                results[node] = {"model": info[node].get("model"), "type": info[node].get("type"),
                                 "watt": nodes.loc[node, Metrics.TIME_SERVICE] * info[node]["WATT"]}
        else:
            for node, attrs in info.items():
                start, end = attrs.get("uptime", (0, None))
                uptime = (end if end else totaltime) - start
                results[node] = {"model": attrs.get("model"), "type": attrs.get("type"),
                                 "watt": uptime * attrs["WATT"], "uptime": uptime}
        return results

    def get_cost_cloud(self, topology: Any) -> tuple[float, dict[Any, dict[str, Any]]]:
        """Cost of service time on nodes with a ``COST`` attribute: ``(total, per node)``.

        YAFS3's ``showResults`` calls this method, which YAFS3 does not define (its draft
        is commented out); this charges service time times ``COST`` on every node that has one.
        """
        if Metrics.TIME_RESPONSE not in self.df.columns:
            self.compute_times_df()
        info = topology.get_info()
        nodes = self.df.groupby("TOPO.dst").agg({Metrics.TIME_SERVICE: "sum"})
        total = 0.0
        results: dict[Any, dict[str, Any]] = {}
        for node in nodes.index:
            cost = info.get(node, {}).get("COST")
            if cost is None:
                continue
            value = float(nodes.loc[node, Metrics.TIME_SERVICE]) * cost
            results[node] = {"model": info[node].get("model"), "cost": value}
            total += value
        return total, results

    def showLoops(self, time_loops: Sequence[Sequence[str]]) -> list[float]:  # noqa: N802 - YAFS name
        """Print and return :meth:`average_loop_response`."""
        results = self.average_loop_response(time_loops)
        for i, loop in enumerate(time_loops):
            print(f"\t\t{i} - {loop!s} :\t {results[i]:f}")
        return results

    def showResults(self, total_time: float, topology: Any, time_loops: Sequence[Sequence[str]] | None = None) -> None:  # noqa: N802
        """Print simulation time, loop delays, energy by uptime and by service, cloud cost
        and bytes transmitted (YAFS3's report)."""
        print(f"\tSimulation Time: {total_time:0.2f}")
        if time_loops is not None:
            print("\tApplication loops delays:")
            self.showLoops(time_loops)
        print("\tEnergy Consumed (WATTS by UpTime):")
        for node, value in self.get_watt(total_time, topology, Metrics.WATT_UPTIME).items():
            print(f"\t\t{node} - {value['model']} :\t {value['watt']:.2f}")
        print("\tEnergy Consumed by Service (WATTS by Service Time):")
        for node, value in self.get_watt(total_time, topology, Metrics.WATT_SERVICE).items():
            print(f"\t\t{node} - {value['model']} :\t {value['watt']:.2f}")
        print("\tCost of execution in cloud:")
        print(f"\t\t{self.get_cost_cloud(topology)[0]:.8f}")
        print("\tNetwork bytes transmitted:")
        print(f"\t\t{self.bytes_transmitted():.1f}")

    def showResults2(self, total_time: float, time_loops: Sequence[Sequence[str]] | None = None) -> None:  # noqa: N802
        """Print simulation time, loop delays and bytes transmitted (YAFS3's short report)."""
        print(f"\tSimulation Time: {total_time:0.2f}")
        if time_loops is not None:
            print("\tApplication loops delays:")
            self.showLoops(time_loops)
        print("\tNetwork bytes transmitted:")
        print(f"\t\t{self.bytes_transmitted():.1f}")

    def valueLoop(self, total_time: float, time_loops: Sequence[Sequence[str]] | None = None) -> float | None:  # noqa: N802
        """The first loop's delay (:meth:`average_loop_response`), or None without loops."""
        if time_loops:
            return self.average_loop_response(time_loops)[0]
        return None

    def average_messages_not_transmitted(self) -> Any:
        """Mean of the ``buffer`` column."""
        return np.mean(self.df_link.buffer)

    def peak_messages_not_transmitted(self) -> Any:
        """Largest ``buffer`` value."""
        return np.max(self.df_link.buffer)

    def messages_not_transmitted(self) -> pd.Series:
        """The last link row's ``buffer``, as a one-row Series (YAFS3)."""
        return self.df_link.buffer[-1:]

    def get_df_modules(self) -> pd.DataFrame:
        """Per module and process (``DES.dst``): mean, sum and count of ``service``."""
        return self.df.groupby(["module", "DES.dst"]).agg({"service": ["mean", "sum", "count"]}).reset_index()

    def get_df_service_utilization(self, service: str, time: float) -> pd.DataFrame:
        """Per process of module ``service``: utilisation in percent of ``time``."""
        table = self.get_df_modules()
        rows = table[table.module == service]
        return pd.DataFrame({"module": rows.module, "utilization": rows["service"]["sum"] * 100 / time})

    # ----------------------------------------------------------------- additions

    def loop_latencies(self, loop: Sequence[str]) -> pd.Series:
        """Per request id, time from the loop's first message emission to its last message's
        service end (``loop`` is a sequence of message names)."""
        first = self.df[self.df["message"] == loop[0]].groupby("id")["time_emit"].min()
        last = self.df[self.df["message"] == loop[-1]].groupby("id")["time_out"].max()
        return (last - first).dropna()
