"""Placements of YAFS's examples/Tutorial, rewritten for the ported main2."""

from yafs_safetail.yafs.placement import Placement


class CloudPlacement(Placement):
    """Every scaled service on the node(s) tagged ``mytag: cloud``, once per replica."""

    def initial_allocation(self, sim, app_name):
        cloud = sim.topology.find_IDs({"mytag": "cloud"})
        app = sim.apps[app_name]
        for module in app.services:
            for _ in range(self.scaleServices.get(module, 0)):
                sim.deploy_module(app_name, module, app.services[module], cloud)
