"""A user who moves: every method's p99 and servers per request at rest, walking and driving.

The command lives in the package, yafs_safetail/commands/mobility_sweep.py (``yafs-safetail
mobility-sweep`` runs the same); ``python experiments/mobility_sweep.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.mobility_sweep import main

if __name__ == "__main__":
    run_script(main)
