"""Many users at once: every method's latency and copies against the offered load.

The command lives in the package, yafs_safetail/commands/load_sweep.py (``yafs-safetail sweep`` runs
the same); ``python experiments/load_sweep.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.load_sweep import main

if __name__ == "__main__":
    run_script(main)
