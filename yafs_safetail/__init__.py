"""yafs-safetail: SafeTail learned redundant edge dispatch on a YAFS-compatible simulator.

Importing the package registers the Gymnasium environment ``yafs_safetail/SafeTail-v0``
(``yafs_safetail.sim.env``; the environment module itself loads on ``gymnasium.make``).
"""

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

ENV_ID = "yafs_safetail/SafeTail-v0"
if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="yafs_safetail.sim.env:SafeTailEnv")
