"""How close the default preset comes to the paper, on seeds the calibration never saw.

Runs ``experiments/reproduce_all.py`` for the three use cases with the given preset (default
``paper``, what ``run_usecase.py`` runs without options) and seeds (default 0-4; the calibration
used 1000-1002, see ``yafs_safetail/edge/calibration.json``), then prints the issue's goals, one
line each, and the verdict:

    ratios_within_20=<hits>/<23>          goal: >= 80 %
    held_out_within_20=<hits>/<11>        goal: >= 70 %
    calibration_within_20=<hits>/<12>     (the fitted subset, for reference)
    claims_hold=<hits>/<11>               goal: all
    access_rate_uc<N>=<mean>              goal: <= 0.5 on every use case
    uc1_default_run_s=<seconds>           goal: <= 30 s on 2 cores (the seed-0 UC1 run's total)
    goals_met=...                         the verdict, one word per goal
    any_policy_ratios_at_most=<lo>-<hi>/23   the most ratios any policy could hold together
                                          within ±20% in these worlds (per seed; results/feasibility.py)
    any_policy_claims_at_most=<k>/11 [unreachable=uc<N>:<key>,...]   claims some policy could make hold

Usage::

    python benchmarks/bench_fidelity.py [--preset paper] [--seeds 0,1,2,3,4] [--out DIR]
        [--steps-scale 1] [--target-compute request|trace_median] [--learning-rate RATE]

About 15 minutes on 2 cores at the full budget. The run folders, REPORT.md and fidelity.csv stay
in ``--out`` (default: a temporary folder, removed at the end).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPOSITORY / "experiments"))

import pandas as pd  # noqa: E402
import reproduce_all  # noqa: E402

from yafs_safetail.cli import positive_float  # noqa: E402
from yafs_safetail.results import feasibility, fidelity  # noqa: E402
from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment  # noqa: E402

GOALS = {"ratios": 0.8, "held-out": 0.7}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="paper")
    parser.add_argument("--seeds", default="0,1,2,3,4")
    parser.add_argument("--steps-scale", default="1")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--target-compute", default=None,
                        help="C(s_j) of Eq. 4 for the reproduction (default: the preset world's)")
    parser.add_argument("--learning-rate", type=positive_float, default=None,
                        help="SafeTail's learning rate instead of the preset's (what the preset's "
                             "network reaches when it can move further; not the preset's result)")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="bench_fidelity_") as scratch:
        out = args.out or Path(scratch) / "reproduce"
        options = [] if args.target_compute is None else ["--target-compute", args.target_compute]
        if args.learning_rate is not None:
            options += ["--learning-rate", repr(args.learning_rate)]
        failed = reproduce_all.main(["--uc", "1,2,3", "--preset", args.preset, "--seeds", args.seeds,
                                     "--steps-scale", args.steps_scale, "--no-figures",
                                     "--out", str(out), *options])
        if failed:  # reproduce_all has said which runs failed and why, one line each
            sys.exit(failed)
        card = pd.read_csv(out / fidelity.FIDELITY_FILE)
        card = card[card["preset"] == args.preset]
        worlds = [feasibility.read_world_run(out / reproduce_all.RUN_FOLDER.format(
                      use_case=use_case, preset=args.preset, seed=int(seed)))
                  for use_case in (1, 2, 3) for seed in args.seeds.split(",")]
        # The UC1 default run, timed alone (reproduce_all's runs share the machine's cores).
        started = time.perf_counter()
        run_experiment(ExperimentConfig(
            use_case=1, preset=args.preset, seed=0, out_dir=Path(scratch) / "uc1", progress=False,
            steps_scale=float(args.steps_scale), learning_rate=args.learning_rate))
        uc1_s = time.perf_counter() - started

    counts = fidelity.counts(card)
    for key, label in (("ratios", "ratios_within_20"), ("held-out", "held_out_within_20"),
                       ("calibration", "calibration_within_20"), ("claims", "claims_hold")):
        hits, total = counts[key]
        print(f"{label}={hits}/{total}")
    access = card[card["kind"] == "access_rate"]
    for row in access.itertuples(index=False):
        print(f"access_rate_uc{row.use_case}={row.ours:.3f}")
    full_budget = float(args.steps_scale) == 1.0
    # The time goal is the full default run's; a smaller budget's time is printed under its own name.
    print(f"uc1_default_run_s={uc1_s:.1f}" if full_budget else f"uc1_run_s_at_scale_{args.steps_scale}={uc1_s:.1f}")
    met = {
        "ratios": counts["ratios"][0] >= GOALS["ratios"] * counts["ratios"][1],
        "held-out": counts["held-out"][0] >= GOALS["held-out"] * counts["held-out"][1],
        "claims": counts["claims"][0] == counts["claims"][1],
        "access": bool((access["ours"] <= fidelity.ACCESS_RATE_GOAL).all()),
        "uc1_time": full_budget and uc1_s <= 30.0,
    }
    print("goals_met=" + ",".join(f"{k}:{'yes' if v else 'no'}" for k, v in met.items()))
    # What no policy could exceed in these worlds (Oracle's and the baselines' runs alone).
    top = feasibility.ceiling(worlds)
    print(f"any_policy_ratios_at_most={top.ratios_low}-{top.ratios_high}/{top.ratios_total}")
    print(f"any_policy_claims_at_most={top.claims}/{top.claims_total}"
          + (f" unreachable={','.join(k.replace(' ', ':') for k in top.unreachable)}" if top.unreachable else ""))


if __name__ == "__main__":
    main()
