"""How long a user waits for a first answer: help, an input error, a quick run, the default run.

Each figure is the median wall time of whole processes, as a user starts them from the checkout:

    help_s       python experiments/run_usecase.py --help
    error_s      python experiments/run_usecase.py --uc 7          (a bad argument: one line)
    quick_s      python experiments/run_usecase.py --uc 1 --steps-scale 0.02   (figures included)
    default_s    python experiments/run_usecase.py --uc 1                      (the full default)

With ``--against-rev REV`` (e.g. 477d812, issue 30's reference) the same commands run in a
temporary worktree of that revision too, interleaved with ours (ours, theirs, ours, ...) so that
a busy machine slows both alike, and ``<name>_ratio=`` gives ours over theirs (medians). Issue
30's goals: help and error ≤ 0.3 s, quick ≤ 0.25 × and default ≤ 0.4 × 477d812's.

Usage::

    python benchmarks/bench_first_answer.py [--runs 5] [--only help,error,quick,default]
        [--against-rev REV]

The temporary worktree and every results folder are the benchmark's own and removed at the end.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
FIGURES = ("help", "error", "quick", "default")


def command(name: str, out: Path) -> list[str]:
    """The user's command for one figure (``out`` is a fresh results folder)."""
    script = ["experiments/run_usecase.py"]
    return {
        "help": [*script, "--help"],
        "error": [*script, "--uc", "7"],
        "quick": [*script, "--uc", "1", "--steps-scale", "0.02", "--out", str(out)],
        "default": [*script, "--uc", "1", "--out", str(out)],
    }[name]


def time_once(checkout: Path, name: str, scratch: Path) -> float:
    """One run's wall time in ``checkout`` (its own package first on the path)."""
    out = Path(tempfile.mkdtemp(prefix=f"{name}-", dir=scratch)) / "run"
    started = time.perf_counter()
    done = subprocess.run([sys.executable, *command(name, out)], cwd=checkout, capture_output=True,
                          text=True, env=_environment(checkout), timeout=3600, check=False)
    elapsed = time.perf_counter() - started
    expected = 2 if name == "error" else 0
    if done.returncode != expected:
        raise SystemExit(f"error: {name} in {checkout} exited {done.returncode}: "
                         f"{done.stderr.strip().splitlines()[-1:]}")
    return elapsed


def _environment(checkout: Path) -> dict[str, str]:
    import os

    environment = dict(os.environ)
    # The checkout's own package, not whichever one is installed.
    environment["PYTHONPATH"] = str(checkout) + os.pathsep + environment.get("PYTHONPATH", "")
    return environment


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="runs per figure (the median; default 5)")
    parser.add_argument("--only", default=",".join(FIGURES),
                        help="figures to measure, comma-separated (default all four)")
    parser.add_argument("--against-rev", default=None,
                        help="a git revision to compare with, run interleaved (e.g. 477d812)")
    args = parser.parse_args(argv)
    args.only = [name for name in args.only.split(",") if name]
    unknown = [name for name in args.only if name not in FIGURES]
    if unknown or not args.only:
        parser.error(f"--only: expected some of {', '.join(FIGURES)}, got {args.only}")
    if args.runs < 1:
        parser.error(f"--runs: expected a positive integer, got {args.runs}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    with tempfile.TemporaryDirectory(prefix="bench_first_answer_") as scratch_name:
        scratch = Path(scratch_name)
        other = None
        if args.against_rev is not None:
            other = scratch / "reference"
            added = subprocess.run(["git", "-C", str(REPOSITORY), "worktree", "add", "--detach",
                                    str(other), args.against_rev], capture_output=True, text=True,
                                   check=False)
            if added.returncode != 0:
                print(f"error: --against-rev {args.against_rev}: {added.stderr.strip()}", file=sys.stderr)
                return 2
        try:
            for name in args.only:
                ours, theirs = [], []
                for _ in range(args.runs):
                    ours.append(time_once(REPOSITORY, name, scratch))
                    if other is not None:
                        theirs.append(time_once(other, name, scratch))
                print(f"{name}_s={statistics.median(ours):.2f}", flush=True)
                if other is not None:
                    print(f"{name}_reference_s={statistics.median(theirs):.2f}")
                    print(f"{name}_ratio={statistics.median(ours) / statistics.median(theirs):.3f}",
                          flush=True)
        finally:
            if other is not None:
                subprocess.run(["git", "-C", str(REPOSITORY), "worktree", "remove", "--force",
                                str(other)], capture_output=True, check=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
