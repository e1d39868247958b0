"""Choose the `paper` preset's learning rate per use case by the rule of docs/calibration.md.

The command lives in the package, yafs_safetail/commands/choose_learning_rate.py (``yafs-safetail learning-rate`` runs
the same); ``python experiments/choose_learning_rate.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.choose_learning_rate import main

if __name__ == "__main__":
    run_script(main)
