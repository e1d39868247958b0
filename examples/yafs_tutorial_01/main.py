"""YAFS3's first tutorial scenario (tutorial_scenarios/01_basicExample), ported.

The only change a YAFS3 script of this shape needs is its imports: ``yafs.X`` becomes
``yafs_safetail.yafs.X``. A binomial-tree network built with networkx, applications and
placement read from JSON, the closest-replica routing, one user per entry of
``data/usersDefinition.json`` emitting every 100 time units.

Run: ``python examples/yafs_tutorial_01/main.py [--until 2000] [--results DIR]``
"""

import argparse
import json
import time
from pathlib import Path

import networkx as nx
import pandas as pd

from yafs_safetail.yafs.application import create_applications_from_json
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.path_routing import DeviceSpeedAwareRouting
from yafs_safetail.yafs.placement import JSONPlacement
from yafs_safetail.yafs.topology import Topology

DATA = Path(__file__).parent / "data"


def main(stop_time, folder_results):
    # Topology: a binomial tree; every link BW = PR = 1, every node IPT = 100.
    t = Topology()
    t.G = nx.generators.binomial_tree(3)
    nx.set_edge_attributes(t.G, name="PR", values=dict.fromkeys(t.G.edges(), 1))
    nx.set_edge_attributes(t.G, name="BW", values=dict.fromkeys(t.G.edges(), 1))
    nx.set_node_attributes(t.G, name="IPT", values=dict.fromkeys(t.G.nodes(), 100))

    apps = create_applications_from_json(json.load(open(DATA / "appDefinition.json")))
    placement = JSONPlacement(name="Placement", json=json.load(open(DATA / "allocDefinition.json")))
    selector_path = DeviceSpeedAwareRouting()

    s = Sim(t, default_results_path=folder_results + "sim_trace")
    for app_name in apps.keys():
        s.deploy_app(apps[app_name], placement, selector_path)

    users = json.load(open(DATA / "usersDefinition.json"))
    for user in users["sources"]:
        app_name = user["app"]
        msg = s.apps[app_name].get_message(user["message"])
        dist = deterministic_distribution(user["lambda"], name="Deterministic")
        s.deploy_source(app_name, id_node=user["id_resource"], msg=msg, distribution=dist)

    s.run(stop_time)
    s.print_debug_assignaments()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="YAFS3 tutorial 01, ported")
    parser.add_argument("--until", type=float, default=2000)
    parser.add_argument("--results", default="results")
    args = parser.parse_args()
    folder = Path(args.results)
    folder.mkdir(parents=True, exist_ok=True)

    start_time = time.time()
    main(stop_time=args.until, folder_results=str(folder) + "/")
    print(f"\n--- {time.time() - start_time} seconds ---")

    dfl = pd.read_csv(str(folder) + "/sim_trace_link.csv")
    print(f"Number of total messages between nodes: {len(dfl)}")
    df = pd.read_csv(str(folder) + "/sim_trace.csv")
    print(f"Number of requests handled by deployed services: {len(df)}")
    dfapp2 = df[df.app == 2].copy()
    dfapp2["service_time"] = dfapp2.time_out - dfapp2.time_in
    print("The average service time of app2 is: {:0.3f} ".format(dfapp2["service_time"].mean()))
    print("The app2 is deployed in the following nodes: {}".format(dfapp2["TOPO.dst"].unique()))
