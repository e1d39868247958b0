"""The plain YAFS-style script of the paper's scenario draws the world a run draws: for a
baseline and seed it prints the figures a run with the same method, seed and test requests
writes into its summary.csv."""

from __future__ import annotations

import contextlib
import csv
import importlib.util
import io
from pathlib import Path

from in_process import run_usecase_here

ROOT = Path(__file__).resolve().parents[1]
SEED = 3
#: UC1's test phase has 20·β = 4000 requests; this scale gives 120 of them.
STEPS_SCALE, TEST_REQUESTS = "0.03", 120


def _example():
    spec = importlib.util.spec_from_file_location("paper_scenario", ROOT / "examples" / "paper_scenario" / "main.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _printed(main, method: str) -> dict[str, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        main(["--uc", "1", "--method", method, "--seed", str(SEED), "--steps", str(TEST_REQUESTS)])
    head, percentiles, target = out.getvalue().splitlines()
    assert head.endswith(f", {method}, {TEST_REQUESTS} requests"), head
    words = percentiles.split()
    return {"p50_s": words[1], "p90_s": words[4], "p95_s": words[7], "p99_s": words[10],
            "fallbacks": target.rsplit(" ", 1)[1]}


def test_the_example_prints_what_a_run_of_the_same_method_seed_and_requests_writes(tmp_path):
    done = run_usecase_here("--uc", "1", "--seed", SEED, "--steps-scale", STEPS_SCALE, "--redundancy", "2",
                            "--no-figures", "--workers", "1", "--out", tmp_path / "run")
    assert done.returncode == 0, done.stderr[-2000:]
    with open(tmp_path / "run" / "summary.csv", newline="", encoding="utf-8") as file:
        summary = {row["method"]: row for row in csv.DictReader(file)}
    main = _example().main
    for method in ("Rand-2", "MinLoad-2", "Oracle"):
        row = summary[method]
        assert int(row["n_requests"]) == TEST_REQUESTS
        expected = {name: f"{float(row[name]):.3f}" for name in ("p50_s", "p90_s", "p95_s", "p99_s")}
        expected["fallbacks"] = str(round(float(row["fallback_rate"]) * TEST_REQUESTS))
        assert _printed(main, method) == expected, method
