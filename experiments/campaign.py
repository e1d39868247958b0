"""Run a grid of experiments as one campaign: each run computed once, resumable, in parallel.

The command lives in the package, yafs_safetail/commands/campaign.py (``yafs-safetail campaign`` runs
the same); ``python experiments/campaign.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.campaign import main

if __name__ == "__main__":
    run_script(main)
