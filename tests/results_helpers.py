"""Synthetic results tables and folders shared by the results tests."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail import results
from yafs_safetail.results import REQUESTS_COLUMNS, RunMetadata

N_SERVERS = 5
BASELINES = [f"{fam}-{x}" for fam in ("Rand", "MinLoad", "MinProp") for x in (1, 2, 3)]


def make_requests(
    rng: np.random.Generator,
    n_train: int = 120,
    n_test: int = 80,
    methods: tuple[str, ...] = ("SafeTail", "Oracle", *BASELINES),
) -> pd.DataFrame:
    """A synthetic requests table in contract form, with common random numbers per request."""
    per_server_s = rng.lognormal(mean=-0.7, sigma=0.4, size=(n_train + n_test, N_SERVERS))
    target_s = np.full(n_train + n_test, 0.55)
    rows = []
    for method in methods:
        family, level = results.parse_method(method)
        phases = [("train", 0, n_train), ("test", n_train, n_test)] if method == "SafeTail" \
            else [("test", n_train, n_test)]
        for phase, start, count in phases:
            for step in range(count):
                request = start + step
                if method == "Oracle":
                    chosen = np.arange(N_SERVERS)
                elif method == "SafeTail":
                    chosen = np.sort(rng.choice(N_SERVERS, size=rng.integers(1, 4), replace=False))
                else:
                    assert level is not None
                    chosen = np.sort(rng.choice(N_SERVERS, size=level, replace=False))
                latency = float(per_server_s[request, chosen].min())
                target = float(target_s[request])
                reward = -0.003 * math.exp(min(latency - target, 5)) if method == "SafeTail" \
                    else math.nan
                fallback = int(rng.random() < 0.01)
                parts = rng.dirichlet(np.ones(4)) * latency
                if fallback:
                    parts = np.full(4, math.nan)
                rows.append({
                    "method": method, "phase": phase, "episode": step // 256, "step": step,
                    "request_id": request, "latency_s": latency, "target_s": target,
                    "deviation_s": target - latency, "n_selected": len(chosen),
                    "access_rate": len(chosen) / N_SERVERS,
                    "servers": ";".join(str(i) for i in chosen), "reward": reward,
                    "refused": int(rng.integers(0, 2)), "fallback": fallback,
                    "upload_s": parts[0], "propagation_s": parts[1], "download_s": parts[2],
                    "compute_s": parts[3],
                })
    return pd.DataFrame(rows, columns=list(REQUESTS_COLUMNS))


def make_run(use_case: int = 1, seed: int = 0, beta: int = 20) -> RunMetadata:
    return RunMetadata(
        use_case=use_case, use_case_name="object detection (YOLOv5)", preset="paper", seed=seed,
        n_servers=N_SERVERS, beta=beta, train_steps=120, test_steps=80,
        topology="topologies/paper_5servers.json", methods=["SafeTail", "Oracle", *BASELINES],
        package_version="0.1.0", command="python experiments/run_usecase.py --uc 1",
    )


def write_run_folder(path, rng: np.random.Generator, use_case: int = 1, seed: int = 0):
    path.mkdir(parents=True, exist_ok=True)
    requests = make_requests(rng)
    results.write_requests_csv(requests, path)
    results.write_run_json(path, make_run(use_case, seed))
    results.write_summary(path)  # reads both files back
    return requests


def write_seed_folders(root: Path, n_seeds: int, rng_seed: int) -> list[Path]:
    """Synthetic run folders ``root/seed<S>`` of use case 1 for seeds 0..n_seeds-1 (each
    drawn from its own generator, ``rng_seed + S``)."""
    paths = [root / f"seed{seed}" for seed in range(n_seeds)]
    for seed, path in enumerate(paths):
        write_run_folder(path, np.random.default_rng(rng_seed + seed), seed=seed)
    return paths


# ---------------------------------------------------------------------------- method names
