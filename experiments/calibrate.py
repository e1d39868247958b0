"""Fit the world parameters the paper never published, without the learner.

The command lives in the package, yafs_safetail/commands/calibrate.py (``yafs-safetail calibrate`` runs
the same); ``python experiments/calibrate.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.calibrate import main

if __name__ == "__main__":
    run_script(main)
