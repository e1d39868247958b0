"""Score your policy in every world: the paper's use cases, many users, failures, a walking user.

The command lives in the package, yafs_safetail/commands/score_policy.py (``yafs-safetail
score`` runs the same); ``python experiments/score_policy.py --help`` lists its options.
"""

from yafs_safetail.cli import run_script
from yafs_safetail.commands.score_policy import main

if __name__ == "__main__":
    run_script(main)
