"""Train SafeTail on one use case, test it against the paper's baselines, write results and figures.

The command lives in the package, yafs_safetail/commands/run_usecase.py (``yafs-safetail run`` runs
the same); ``python experiments/run_usecase.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.run_usecase import main

if __name__ == "__main__":
    run_script(main)
