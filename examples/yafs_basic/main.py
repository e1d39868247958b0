"""A YAFS3-style script: users and edge servers from JSON, redundant dispatch, first reply wins.

Each user's frame is sent to its two lowest-propagation edge servers (two copies of one
request, one ``id``); each server runs the detector and replies to the user's sink. The
selection is told each request's outcome (``on_request_complete``) and keeps the fastest
reply, and ``analysis.load_results`` summarises the results files.

Run: ``python examples/yafs_basic/main.py [--until 60] [--copies 2] [--results DIR]``
"""

import argparse
import json
from pathlib import Path

import networkx as nx

from yafs_safetail.yafs.analysis import load_results
from yafs_safetail.yafs.application import create_applications_from_json
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import exponential_distribution
from yafs_safetail.yafs.placement import JSONPlacement
from yafs_safetail.yafs.selection import Selection
from yafs_safetail.yafs.topology import Topology

HERE = Path(__file__).parent


class LowestPropagation(Selection):
    """Frames to the ``copies`` servers with the lowest total PR; replies to the user's sink."""

    def __init__(self, copies):
        super().__init__()
        self.copies = copies
        self.first_reply_s = []
        self.unanswered = 0

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        G = sim.topology.G
        if message.dst == "Client":
            user_node = alloc_DES[message.original_DES_src]
            sink = next(d for d in alloc_module[app_name]["Client"] if alloc_DES[d] == user_node)
            return [nx.shortest_path(G, topology_src, user_node)], [sink]
        ranked = sorted(
            alloc_module[app_name][message.dst],
            key=lambda des: nx.shortest_path_length(G, topology_src, alloc_DES[des], weight="PR"),
        )[: self.copies]
        return [nx.shortest_path(G, topology_src, alloc_DES[d], weight="PR") for d in ranked], ranked

    def on_request_complete(self, sim, outcome):
        if outcome.first is None:
            self.unanswered += 1
        else:
            self.first_reply_s.append(outcome.latency)


def main(until, copies, folder_results, seed=1):
    t = Topology()
    t.load(HERE / "topology.json")
    apps = create_applications_from_json(HERE / "appDefinition.json")
    placement = JSONPlacement(name="edge", json=HERE / "allocDefinition.json")
    selection = LowestPropagation(copies)

    # Replies are routed back to the user that sent the frame: the ``direct`` engine lets
    # module outputs keep the request's ``original_DES_src`` (YAFS3 resets it to None).
    s = Sim(t, default_results_path=folder_results + "sim_trace", engine="direct")
    for app in apps.values():
        s.deploy_app(app, placement, selection)

    users = json.load(open(HERE / "usersDefinition.json"))
    for index, user in enumerate(users["sources"]):
        msg = s.apps[user["app"]].get_message(user["message"])
        dist = exponential_distribution(user["lambda"], seed=seed + index, integer=False)
        s.deploy_source(user["app"], id_node=user["id_resource"], msg=msg, distribution=dist)
        s.deploy_sink(user["app"], node=user["id_resource"], module="Client")

    s.run(until)
    return selection


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="YAFS3-style redundant dispatch example")
    parser.add_argument("--until", type=float, default=60)
    parser.add_argument("--copies", type=int, default=2)
    parser.add_argument("--results", default="results")
    args = parser.parse_args()
    folder = Path(args.results)
    folder.mkdir(parents=True, exist_ok=True)

    selection = main(args.until, args.copies, str(folder) + "/")
    replies = sorted(selection.first_reply_s)
    print(f"requests answered: {len(replies)}, unanswered: {selection.unanswered}")
    if replies:
        print(f"first-reply latency: median {replies[len(replies) // 2]:.4f}, max {replies[-1]:.4f}")
    results = load_results(str(folder) + "/sim_trace")
    print(results.percentiles())
