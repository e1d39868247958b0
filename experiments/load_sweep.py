"""Many users at once: every method's latency and copies against the offered load.

The command lives in the package, yafs_safetail/commands/load_sweep.py (``yafs-safetail sweep`` runs
the same); ``python experiments/load_sweep.py --help`` lists its options.
"""

import sys

from yafs_safetail.cli import run_cli
from yafs_safetail.commands.load_sweep import main

if __name__ == "__main__":
    sys.exit(run_cli(main))
