"""Why the paper's learner collapses under contention: copies and queue length over training.

The command lives in the package, yafs_safetail/commands/training_mechanism.py (``yafs-safetail
mechanism`` runs the same); ``python experiments/training_mechanism.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.training_mechanism import main

if __name__ == "__main__":
    run_script(main)
