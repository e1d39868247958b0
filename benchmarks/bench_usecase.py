"""Wall time of the full UC1 run, and where it goes.

The run is what ``python experiments/run_usecase.py --uc 1`` does: paper preset, the full step
budget (50·β training steps, then 20·β test steps for SafeTail and for every baseline:
Oracle, Rand-x, MinLoad-x, MinProp-x with x = 1, 2, 3) and the figures (``--yafs-csv``: also
the YAFS result CSVs, which the default run no longer writes), into a temporary folder, in this one process through ``run_experiment``.

The split (seconds of wall time): setup (checks, traces, worlds, the learner) with the
TensorFlow/Keras import shown separately; simulation in this process (the core plus the edge
model's hooks and the selections' bookkeeping, without the learner's share); decisions (state
encoding and action choice); training (storing tuples and training rounds); with
``--workers 2`` (the default) the baselines' test phase runs in a forked process beside the
above: its wall time, and how long this process then waited for it; writing
(requests/summary/run files and the policy); plotting; what is left over (records frames,
moving the folder into place); and the package imports. The last line is
``folder_mb=`` (the results folder's size) and ``total_s=<number>``: imports plus the run. The ``cpu`` line is this process's CPU time, for comparing runs on a busy machine.

Usage::

    python benchmarks/bench_usecase.py [--uc 1] [--preset paper] [--steps-scale 1] [--seed 0]
        [--workers 2]
        [--profile FILE]   # also write a cProfile of the run to FILE
"""

from __future__ import annotations

import argparse
import time

STARTED = time.perf_counter()
STARTED_CPU = time.process_time()

import os  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment  # noqa: E402

IMPORTED = time.perf_counter()

#: Report order of the run's timings (``ExperimentReport.timings_s``).
PARTS = ("setup", "tf_import", "simulation", "decisions", "training", "baselines_in_workers",
         "waiting_for_workers", "writing", "plotting")
#: Parts inside another part, or overlapping this process's time (not added to the total).
NOT_ADDED = {"tf_import": "part of setup", "baselines_in_workers": "in worker processes, overlapped"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--uc", type=int, default=1)
    parser.add_argument("--preset", default="paper")
    parser.add_argument("--steps-scale", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2,
                        help="processes (default 2: the baselines run beside SafeTail's training)")
    parser.add_argument("--profile", type=Path, default=None, help="write a cProfile of the run here")
    parser.add_argument("--yafs-csv", action="store_true", help="also write the YAFS result CSVs")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="bench_usecase_") as tmp:
        config = ExperimentConfig(
            use_case=args.uc, preset=args.preset, seed=args.seed, out_dir=Path(tmp) / "run",
            steps_scale=args.steps_scale, redundancy_levels=(1, 2, 3), write_yafs_csv=args.yafs_csv,
            figures=True, progress=False, command="benchmarks/bench_usecase.py", workers=args.workers,
        )
        if args.profile is None:
            report = run_experiment(config)
        else:
            import cProfile

            profiler = cProfile.Profile()
            report = profiler.runcall(run_experiment, config)
            profiler.dump_stats(args.profile)
        n_rows = int(report.summary["n_requests"].sum())
        folder_bytes = sum(f.stat().st_size for f in report.out_dir.rglob("*") if f.is_file())

    timings = report.timings_s
    imports_s = IMPORTED - STARTED
    print(f"UC{args.uc} preset={args.preset} steps_scale={args.steps_scale} seed={args.seed} "
          f"workers={args.workers}: "
          f"{len(report.summary)} methods, {n_rows} test requests")
    width = max(map(len, PARTS)) + 2
    for part in PARTS:
        note = f"  ({NOT_ADDED[part]})" if part in NOT_ADDED else ""
        print(f"{part:<{width}}{timings.get(part, 0.0):8.2f} s{note}")
    accounted = sum(timings.get(part, 0.0) for part in PARTS if part not in NOT_ADDED)
    print(f"{'other':<{width}}{timings['total'] - accounted:8.2f} s  (records frames, publishing)")
    print(f"{'run':<{width}}{timings['total']:8.2f} s")
    # On a shared machine wall time includes waiting for a core; CPU time does not.
    children = os.times()
    print(f"{'cpu':<{width}}{time.process_time() - STARTED_CPU:8.2f} s  (this process, all threads)")
    print(f"{'cpu_workers':<{width}}{children.children_user + children.children_system:8.2f} s  "
          "(the worker processes)")
    print(f"{'imports':<{width}}{imports_s:8.2f} s")
    print(f"folder_mb={folder_bytes / 1e6:.1f}")
    print(f"total_s={imports_s + timings['total']:.2f}")


if __name__ == "__main__":
    main()
