"""Compare two results folders: each method's test-phase p50/p90/p95/p99 and servers per request

The command lives in the package, yafs_safetail/commands/compare_runs.py (``yafs-safetail compare`` runs
the same); ``python experiments/compare_runs.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.compare_runs import main

if __name__ == "__main__":
    run_script(main)
