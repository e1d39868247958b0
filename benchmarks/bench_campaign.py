"""Campaign throughput: the same 12-run campaign with 1 and 2 workers, local and Ray.

Each configuration runs the whole campaign (UC1, paper preset, seeds 0-11, no figures, the
given step scale) into a fresh temporary folder through ``runs.campaign.run_campaign``, so it
pays everything a user pays: worker start-up (one TensorFlow import per worker process), the
runs, and for Ray the runtime's start and shutdown. Printed: wall time per configuration, the
speed-up of 2 workers over 1 per engine, Ray's overhead against the local engine at the same
worker count, and whether every configuration wrote byte-identical run folders.

Goal: 2 workers >= 1.8x one worker; Ray's wall time <= 1.10x the local engine's.

Usage::

    python benchmarks/bench_campaign.py [--runs 12] [--steps-scale 1] [--engines local,ray]
"""

from __future__ import annotations

import argparse
import io
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from yafs_safetail.logs import RUN_LOG_FILE
from yafs_safetail.runs.campaign import run_campaign
from yafs_safetail.runs.grid import expand


def _folder_bytes(folder: Path) -> dict[str, bytes]:
    # Run folders only, not the campaign's state; not run.log either, whose times differ.
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.parent != folder and p.name != RUN_LOG_FILE}


def _start_ray(workers: int) -> Any:
    """A local Ray runtime as ``--engine ray`` starts it (RayEngine), returned as the module."""
    import ray

    from yafs_safetail.runs.engines import ONE_CORE_ENV

    ray.init(num_cpus=workers, runtime_env={"env_vars": dict(ONE_CORE_ENV)}, log_to_driver=False,
             include_dashboard=False, _system_config={"worker_niceness": 0})
    return ray


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=12, help="runs in the campaign (seeds 0..runs-1)")
    # Full-size runs by default: a campaign's runs are real runs, and at a tiny scale the
    # workers' fixed start-up (TensorFlow's import, ~5-9 s each) is most of the wall time.
    parser.add_argument("--steps-scale", type=float, default=1.0, help="each run's step scale")
    parser.add_argument("--engines", default="local,ray", help="engines to measure (local,ray)")
    args = parser.parse_args()
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    specs = expand({"steps_scale": args.steps_scale, "figures": False},
                   {"use_case": [1], "seed": list(range(args.runs))})
    wall_s: dict[tuple[str, int], float] = {}
    files: dict[tuple[str, int], dict[str, bytes]] = {}
    start_s: dict[int, float] = {}
    print(f"campaign: {len(specs)} runs of UC1 at steps-scale {args.steps_scale}; "
          f"{os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory(prefix="bench-campaign-") as scratch:
        for engine in args.engines.split(","):
            for workers in (1, 2):
                out = Path(scratch) / f"{engine}-{workers}"
                started = time.perf_counter()
                if engine == "ray":
                    # Started here, not by the campaign, to show its start apart: a campaign on
                    # an existing cluster (--ray-address) does not pay it.
                    ray_started = _start_ray(workers)
                    start_s[workers] = time.perf_counter() - started
                    print(f"  (Ray runtime start, {workers} CPU(s): {start_s[workers]:.1f} s)", flush=True)
                result = run_campaign(specs, out, engine=engine, workers=workers, stream=io.StringIO())
                if engine == "ray":
                    ray_started.shutdown()
                wall_s[engine, workers] = time.perf_counter() - started
                if result.failed:
                    raise SystemExit(f"{engine} x{workers}: {result.failed} run(s) failed: "
                                     f"{[r.error for r in result.runs if r.error][0]}")
                files[engine, workers] = _folder_bytes(out)
                print(f"{engine:>5} engine, {workers} worker(s): {wall_s[engine, workers]:7.1f} s "
                      f"({len(specs) / wall_s[engine, workers] * 60:.1f} runs/min)", flush=True)
    print()
    for engine in args.engines.split(","):
        print(f"speed-up {engine} 2 workers / 1 worker: {wall_s[engine, 1] / wall_s[engine, 2]:.2f}x")
    if ("ray", 1) in wall_s and ("local", 1) in wall_s:
        for workers in (1, 2):
            overhead = wall_s["ray", workers] / wall_s["local", workers] - 1
            without_start = (wall_s["ray", workers] - start_s[workers]) / wall_s["local", workers] - 1
            print(f"Ray overhead vs local, {workers} worker(s): {overhead:+.1%} "
                  f"({without_start:+.1%} without the runtime's start)")
    reference = next(iter(files.values()))
    same = all(f == reference for f in files.values())
    print(f"run folders byte-identical across configurations: {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
