"""Servers that fail: every method's success rate, p99 and energy per request as failures rise.

The command lives in the package, yafs_safetail/commands/failure_sweep.py (``yafs-safetail
failure-sweep`` runs the same); ``python experiments/failure_sweep.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.failure_sweep import main

if __name__ == "__main__":
    run_script(main)
