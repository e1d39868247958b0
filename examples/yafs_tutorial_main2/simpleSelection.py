"""Selections of YAFS's examples/Tutorial, rewritten for the ported main2."""

import networkx as nx

from yafs_safetail.yafs.selection import Selection


class MinPath_RoundRobin(Selection):
    """Sensor messages go to the service replicas in turn; other messages go to every
    destination replica when they are broadcasting, else to the last one."""

    def __init__(self):
        self.rr = {}  # module name -> index of the next replica to use

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        replicas = alloc_module[app_name][message.dst]
        index = self.rr.setdefault(message.dst, 0)
        if message.name == "M.A":
            des = replicas[index]
            self.rr[message.dst] = (index + 1) % len(replicas)
            return [list(nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des]))], [des]
        paths = [list(nx.shortest_path(sim.topology.G, topology_src, alloc_DES[des])) for des in replicas]
        if message.broadcasting:
            return paths, list(replicas)
        return paths[-1:], list(replicas[-1:])
