"""How long the scoring suite takes: ``score_policy.py`` with each profile, from an empty folder.

Runs ``experiments/score_policy.py --method examples/custom_policy/nearest_free.py:NearestFree``
with ``--profile quick`` (the promise: a few minutes on two cores) and, with ``--full``, with
``--profile full`` too (hours on two cores: what a cluster or an overnight run is for), each
into a fresh temporary folder, and prints each profile's wall time and its runs' own times per
scenario (from the campaign's ``campaign.json``), the rest being start-up and the report.

    python benchmarks/bench_score_policy.py [--full] [--workers N]

Leave the machine otherwise idle: the figure is a wall time, not a ratio.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
POLICY = ROOT / "examples" / "custom_policy" / "nearest_free.py"


def one_profile(profile: str, workers: int | None) -> tuple[float, dict[str, float]]:
    """The suite's wall time and each scenario's summed run time, in seconds."""
    with tempfile.TemporaryDirectory(prefix=f"score-{profile}-") as folder:
        out = Path(folder) / "score"
        command = [sys.executable, str(ROOT / "experiments" / "score_policy.py"), "--method",
                   f"{POLICY}:NearestFree", "--profile", profile, "--out", str(out), "--quiet"]
        if workers is not None:
            command += ["--workers", str(workers)]
        start = time.perf_counter()
        subprocess.run(command, check=True)
        wall_s = time.perf_counter() - start
        per_scenario: dict[str, float] = defaultdict(float)
        for run in json.loads((out / "campaign.json").read_text())["runs"]:
            per_scenario[run["name"].split("/")[0]] += float(run.get("wall_s") or 0.0)
    return wall_s, dict(per_scenario)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also time the full profile (hours on 2 cores)")
    parser.add_argument("--workers", type=int, default=None, help="runs at a time (default: every core)")
    args = parser.parse_args()
    for profile in ("quick", "full") if args.full else ("quick",):
        wall_s, per_scenario = one_profile(profile, args.workers)
        print(f"{profile}: {wall_s:.0f} s wall ({wall_s / 60:.1f} min)")
        for scenario, seconds in per_scenario.items():
            print(f"  {scenario:<10} {seconds:7.1f} s of runs")


if __name__ == "__main__":
    main()
