"""Throughput of the YAFS-compatible core on SafeTail's shape of traffic.

1 user - 1 access point - 5 edge servers; every request is multicast to all 5 servers
(5 copies), each copy is served and answered back to the user's sink; default YAFS delay
hooks (link queues on) and result files written to a temporary directory. Prints request
copies per wall-clock second, result rows (module + sink + link rows) per second and the
peak resident memory (rates per wall-clock second, and per CPU second of this process,
which is what the wall figure would be on an otherwise idle machine); then the same with a concurrent service model (what the edge model
uses) and with result files off.

Run: ``python benchmarks/bench_core.py [--requests 20000]``
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

from yafs_safetail.yafs.application import Application, Message
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.hooks import YAFSServiceModel
from yafs_safetail.yafs.placement import Placement
from yafs_safetail.yafs.population import Population
from yafs_safetail.yafs.selection import Selection
from yafs_safetail.yafs.topology import Topology

USER, ACCESS_POINT = 0, 1
SERVERS = [2, 3, 4, 5, 6]
PERIOD = 1.0


class MulticastToAll(Selection):
    """Requests to every server replica; replies back to the user's sink (paths precomputed)."""

    def __init__(self) -> None:
        super().__init__()
        self.completed = 0
        self._up: tuple[list[list[int]], list[int]] | None = None
        self._down: dict[int, tuple[list[list[int]], list[int]]] = {}

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        if message.name == "Req":
            if self._up is None:
                replicas = alloc_module[app_name]["Service"]
                self._up = ([[USER, ACCESS_POINT, alloc_DES[d]] for d in replicas], list(replicas))
            return self._up
        down = self._down.get(topology_src)
        if down is None:
            sink = alloc_module[app_name]["Client"][0]
            down = ([[topology_src, ACCESS_POINT, USER]], [sink])
            self._down[topology_src] = down
        return down

    def on_request_complete(self, sim, outcome):
        self.completed += 1


class OnServers(Placement):
    def initial_allocation(self, sim, app_name):
        services = sim.apps[app_name].services["Service"]
        for node in SERVERS:
            sim.deploy_module(app_name, "Service", services, [node])


class OneUser(Population):
    def initial_allocation(self, sim, app_name):
        app = sim.apps[app_name]
        sim.deploy_source(app_name, id_node=USER, msg=app.get_message("Req"),
                          distribution=deterministic_distribution(PERIOD))
        sim.deploy_sink(app_name, node=USER, module="Client")


class ConcurrentService(YAFSServiceModel):
    concurrent = True


def build(results_path: str | None, service_model=None) -> tuple[Sim, MulticastToAll]:
    topology = Topology()
    topology.load({
        "entity": [{"id": USER, "IPT": 1}, {"id": ACCESS_POINT, "IPT": 1}]
        + [{"id": s, "IPT": 1000 * (i + 1)} for i, s in enumerate(SERVERS)],
        "link": [{"s": USER, "d": ACCESS_POINT, "BW": 100, "PR": 0.002}]
        + [{"s": ACCESS_POINT, "d": s, "BW": 50, "PR": 0.005 * (i + 1)} for i, s in enumerate(SERVERS)],
    })
    app = Application("safetail")
    app.set_modules([{"User": {"Type": Application.TYPE_SOURCE}},
                     {"Service": {"RAM": 1, "Type": Application.TYPE_MODULE}},
                     {"Client": {"Type": Application.TYPE_SINK}}])
    request = Message("Req", "User", "Service", instructions=100, bytes=200_000)
    reply = Message("Resp", "Service", "Client", instructions=0, bytes=50_000)
    app.add_source_messages(request)
    app.add_service_module("Service", request, reply)
    sim = Sim(topology, default_results_path=results_path, service_model=service_model,
              write_results=results_path is not None)
    selection = MulticastToAll()
    sim.deploy_app(app, OnServers("servers"), OneUser("user"), selection)
    return sim, selection


def measure(label: str, requests: int, results_dir: Path | None, service_model=None) -> None:
    path = str(results_dir / label) if results_dir is not None else None
    sim, selection = build(path, service_model)
    start, start_cpu = time.perf_counter(), time.process_time()
    sim.run(requests * PERIOD + PERIOD / 2)
    wall_s = time.perf_counter() - start
    cpu_s = time.process_time() - start_cpu
    copies = selection.completed * len(SERVERS)
    rows = 0
    if path is not None:
        for suffix in (".csv", "_link.csv"):
            with open(path + suffix, "rb") as handle:
                rows += sum(1 for _ in handle) - 1
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{label:<24} requests={selection.completed:>6}  wall={wall_s:5.2f} s "
          f"(cpu {cpu_s:5.2f} s)  copies/s={copies / wall_s:>7,.0f} (cpu {copies / cpu_s:>7,.0f})  "
          f"rows/s={rows / wall_s:>8,.0f} (cpu {rows / cpu_s:>8,.0f})  peak RSS={peak_mib:5.1f} MiB")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=20_000, help="requests to simulate")
    args = parser.parse_args(argv)
    print(f"Python {sys.version.split()[0]}; {args.requests} requests x {len(SERVERS)} copies")
    with tempfile.TemporaryDirectory() as tmp:
        measure("yafs-fifo+results", args.requests, Path(tmp))
        measure("concurrent+results", args.requests, Path(tmp), ConcurrentService())
        measure("concurrent, no results", args.requests, None, ConcurrentService())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
