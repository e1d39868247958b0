"""YAFS's ``stats.Stats``: summaries read back from the results CSVs."""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from yafs_safetail.yafs.analysis import load_results


class Stats:
    """Read ``<defaultPath>.csv`` and ``<defaultPath>_link.csv`` and summarise them.

    Attributes:
        df: the module/sink rows with YAFS's derived columns (``time_latency``,
            ``time_wait``, ``time_service``, ``time_response``, ``time_total_response``).
        df_link: the link rows.
    """

    def __init__(self, defaultPath: str = "result") -> None:  # noqa: N803 - YAFS name
        results = load_results(defaultPath)
        self.df = results.events
        self.df_link = results.links
        self.compute_times_df()

    def compute_times_df(self) -> None:
        """Add YAFS's time columns to :attr:`df`."""
        df = self.df
        df["time_latency"] = df["time_reception"] - df["time_emit"]
        df["time_wait"] = df["time_in"] - df["time_reception"]
        df["time_service"] = df["time_out"] - df["time_in"]
        df["time_response"] = df["time_out"] - df["time_reception"]
        df["time_total_response"] = df["time_response"] + df["time_latency"]

    def count_messages(self) -> int:
        """Number of module/sink rows."""
        return len(self.df)

    def bytes_transmitted(self) -> int:
        """Bytes summed over every hop."""
        return int(self.df_link["size"].sum())

    def average_messages_not_transmitted(self) -> float:
        """Mean number of messages in flight on links when a hop starts."""
        return float(self.df_link["buffer"].mean()) if len(self.df_link) else 0.0

    def peak_messages_not_transmitted(self) -> int:
        """Largest number of messages in flight on links when a hop started."""
        return int(self.df_link["buffer"].max()) if len(self.df_link) else 0

    def messages_not_transmitted(self) -> int:
        """Messages in flight when the last hop started."""
        return int(self.df_link["buffer"].iloc[-1]) if len(self.df_link) else 0

    def get_df_modules(self) -> pd.DataFrame:
        """Per replica (``DES.dst``): module, node, messages served and mean service time."""
        return (self.df.groupby("DES.dst")
                .agg(module=("module", "first"), node=("TOPO.dst", "first"),
                     messages=("id", "size"), service_mean=("service", "mean"))
                .reset_index())

    def get_df_service_utilization(self, service: str, time: float) -> pd.DataFrame:
        """Per replica of ``service``: busy time and utilisation over ``time``."""
        rows = self.df[self.df["module"] == service]
        table = rows.groupby("DES.dst").agg(busy=("service", "sum"), messages=("id", "size"))
        table["utilization"] = table["busy"] / time
        return table.reset_index()

    def utilization(self, id_entity: object, total_time: float, from_time: float = 0.0) -> float:
        """Busy fraction of node ``id_entity`` from ``from_time`` to ``total_time``."""
        rows = self.df[(self.df["TOPO.dst"] == id_entity) & (self.df["time_in"] >= from_time)]
        return float(rows["service"].sum()) / (total_time - from_time)

    def loop_latencies(self, loop: Sequence[str]) -> pd.Series:
        """Per request id, time from the loop's first message emission to its last message's
        service end (``loop`` is a sequence of message names)."""
        first = self.df[self.df["message"] == loop[0]].groupby("id")["time_emit"].min()
        last = self.df[self.df["message"] == loop[-1]].groupby("id")["time_out"].max()
        return (last - first).dropna()

    def showResults2(self, total_time: float, time_loops: Sequence[Sequence[str]] | None = None) -> None:  # noqa: N802
        """Print a YAFS-style summary."""
        print("\tSimulation time:", total_time)
        for loop in time_loops or []:
            latencies = self.loop_latencies(loop)
            print(f"\tLoop {list(loop)}: mean {latencies.mean():.6g} over {len(latencies)} requests")
        print("\tMessages processed:", self.count_messages())
        print("\tBytes transmitted:", self.bytes_transmitted())
        print("\tAverage messages in flight:", round(self.average_messages_not_transmitted(), 3))
        print("\tPeak messages in flight:", self.peak_messages_not_transmitted())
        print(self.get_df_modules().to_string(index=False))
