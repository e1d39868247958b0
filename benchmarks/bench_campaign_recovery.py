"""What a worker killed outright costs a campaign: the extra wall time against an uncut campaign.

Runs the same small campaign (UC1, paper preset, seeds 0..runs-1, no figures) three times
through ``runs.campaign.run_campaign``, each from scratch:

1. uncut, into a fresh folder;
2. with one run's worker killed by SIGKILL (``engines.KILL_RUN_ENV``: at the worst moment, the
   run's results all written, just before they would be renamed into place), into another
   fresh folder: that run fails, the others finish;
3. the same campaign again on that folder (what a user does next): the killed run only.

Printed: each wall time, ``extra_s`` = (2) + (3) - (1) and the ratio ((2) + (3)) / (1), and
whether the recovered campaign's run folders equal the uncut one's byte for byte (run.log
aside, which holds times). The extra time is one lost run plus the start of two worker
processes (the killed worker's replacement and the rerun's worker; one TensorFlow import each).

Usage::

    python benchmarks/bench_campaign_recovery.py [--runs 4] [--steps-scale 0.05] [--workers 2] [--kill 0]
"""

from __future__ import annotations

import argparse
import io
import os
import tempfile
import time
from pathlib import Path

from yafs_safetail.logs import RUN_LOG_FILE
from yafs_safetail.runs.campaign import run_campaign
from yafs_safetail.runs.engines import KILL_RUN_ENV
from yafs_safetail.runs.grid import RunSpec, expand


def _folder_bytes(folder: Path) -> dict[str, bytes]:
    # Run folders only, not the campaign's state; not run.log either, whose times differ.
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.parent != folder and p.name != RUN_LOG_FILE}


def _timed(specs: list[RunSpec], out: Path, workers: int) -> tuple[float, int]:
    """(wall seconds, failed runs) of one campaign."""
    started = time.perf_counter()
    result = run_campaign(specs, out, workers=workers, stream=io.StringIO())
    return time.perf_counter() - started, result.failed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=4, help="runs in the campaign (seeds 0..runs-1)")
    parser.add_argument("--steps-scale", type=float, default=0.05, help="each run's step scale")
    parser.add_argument("--workers", type=int, default=2, help="local worker processes")
    parser.add_argument("--kill", type=int, default=0, help="index of the run whose worker is killed")
    args = parser.parse_args()
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    specs = expand({"steps_scale": args.steps_scale, "figures": False},
                   {"use_case": [1], "seed": list(range(args.runs))})
    victim = specs[args.kill]
    with tempfile.TemporaryDirectory(prefix="bench-recovery-") as scratch:
        uncut, recovered = Path(scratch) / "uncut", Path(scratch) / "killed"
        uncut_s, uncut_failed = _timed(specs, uncut, args.workers)
        os.environ[KILL_RUN_ENV] = victim.name  # read by the spawned workers
        try:
            killed_s, killed_failed = _timed(specs, recovered, args.workers)
        finally:
            del os.environ[KILL_RUN_ENV]
        rerun_s, rerun_failed = _timed(specs, recovered, args.workers)
        identical = _folder_bytes(uncut) == _folder_bytes(recovered)
    if (uncut_failed, killed_failed, rerun_failed) != (0, 1, 0):
        raise SystemExit(f"unexpected failures: uncut {uncut_failed}, killed {killed_failed}, "
                         f"rerun {rerun_failed} (expected 0, 1, 0)")
    extra_s = killed_s + rerun_s - uncut_s
    print(f"campaign: {args.runs} runs of UC1 at --steps-scale {args.steps_scale}, {args.workers} "
          f"workers; run {victim.name}'s worker killed (SIGKILL) just before publishing")
    print(f"uncut_s={uncut_s:.1f} killed_s={killed_s:.1f} rerun_s={rerun_s:.1f}")
    print(f"extra_s={extra_s:.1f} ratio={(killed_s + rerun_s) / uncut_s:.2f}x "
          f"(killed + rerun against uncut)")
    print(f"run folders identical to the uncut campaign's: {identical}")


if __name__ == "__main__":
    main()
