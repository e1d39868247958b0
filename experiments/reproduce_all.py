"""Run every use case over several seeds and write one report against the paper's numbers.

The command lives in the package, yafs_safetail/commands/reproduce_all.py (``yafs-safetail reproduce`` runs
the same); ``python experiments/reproduce_all.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.reproduce_all import main

if __name__ == "__main__":
    run_script(main)
