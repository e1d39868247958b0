"""YAFS3's examples/Tutorial/main2.py scenario, ported (imports changed to yafs_safetail.yafs).

Sensor -> ServiceA (4 replicas in the cloud, round robin) -> broadcast to 2 actuator sinks:
each reply is multicast, and the second copy queues behind the first on the cloud-actuator
link (arrivals at +1.0005 and +2.001 after the service ends).

Run: ``python examples/yafs_tutorial_main2/main.py [--until 1000] [--results DIR]``
"""

import argparse
import time
from pathlib import Path

import networkx as nx
from simplePlacement import CloudPlacement
from simpleSelection import MinPath_RoundRobin

from yafs_safetail.yafs.application import Application, Message, fractional_selectivity
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.population import Statical
from yafs_safetail.yafs.stats import Stats
from yafs_safetail.yafs.topology import Topology


def create_application():
    a = Application(name="SimpleCase")
    a.set_modules([{"Sensor": {"Type": Application.TYPE_SOURCE}},
                   {"ServiceA": {"RAM": 10, "Type": Application.TYPE_MODULE}},
                   {"Actuator": {"Type": Application.TYPE_SINK}}])
    m_a = Message("M.A", "Sensor", "ServiceA", instructions=20 * 10**6, bytes=1000)
    m_b = Message("M.B", "ServiceA", "Actuator", instructions=30 * 10**6, bytes=500, broadcasting=True)
    a.add_source_messages(m_a)
    a.add_service_module("ServiceA", m_a, m_b, fractional_selectivity, threshold=1.0)
    return a


def create_json_topology():
    cloud = {"id": 0, "model": "cloud", "mytag": "cloud", "IPT": 5000 * 10**6, "RAM": 40000}
    sensor = {"id": 1, "model": "sensor-device", "IPT": 100 * 10**6, "RAM": 4000}
    actuator = {"id": 2, "model": "actuator-device", "IPT": 100 * 10**6, "RAM": 4000}
    return {"entity": [cloud, sensor, actuator],
            "link": [{"s": 0, "d": 1, "BW": 1, "PR": 10}, {"s": 0, "d": 2, "BW": 1, "PR": 1}]}


def main(simulated_time, folder_results):
    t = Topology()
    t.load(create_json_topology())
    nx.write_gexf(t.G, folder_results + "graph_main2")

    app = create_application()

    placement = CloudPlacement("onCloud")
    placement.scaleService({"ServiceA": 4})

    pop = Statical("Statical")
    pop.set_sink_control({"model": "actuator-device", "number": 2, "module": app.get_sink_modules()})
    d_distribution = deterministic_distribution(name="Deterministic", time=100)
    pop.set_src_control({"model": "sensor-device", "number": 1, "message": app.get_message("M.A"),
                         "distribution": d_distribution})

    selector_path = MinPath_RoundRobin()

    s = Sim(t, default_results_path=folder_results + "sim_trace")
    s.deploy_app2(app, placement, pop, selector_path)
    s.run(simulated_time, show_progress_monitor=False)
    s.print_debug_assignaments()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="YAFS3 Tutorial main2, ported")
    parser.add_argument("--until", type=float, default=1000)
    parser.add_argument("--results", default="results")
    args = parser.parse_args()
    folder = Path(args.results)
    folder.mkdir(parents=True, exist_ok=True)

    start_time = time.time()
    main(simulated_time=args.until, folder_results=str(folder) + "/")
    print("\n--- %s seconds ---" % (time.time() - start_time))

    m = Stats(defaultPath=str(folder) + "/sim_trace")
    m.showResults2(args.until, time_loops=[["M.A", "M.B"]])
    print("\t- Network saturation -")
    print(f"\t\tAverage waiting messages : {m.average_messages_not_transmitted():.3f}")
    print(f"\t\tPeak of waiting messages : {m.peak_messages_not_transmitted()}")
    print(m.get_df_service_utilization("ServiceA", args.until))
