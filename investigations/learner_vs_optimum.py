"""SafeTail beside what its own training target can reach, per use case.

Under §III's target vector SafeTail learns the subset that most often earns an Eq. 5 reward of
exactly 0. The learner-free "most zeros" policy (``yafs_safetail.runs.most_zeros``: fitted
on the world-calibration seeds, keyed on each server's active users and the input size's and
the user's uplink's terciles) is what that target reaches without a learner's limits. This
prints, per use case, SafeTail's share of zero rewards and access rate (mean over seeds) beside
the policy's on the very same test requests, the gaps, and the goals: SafeTail's share
of zeros no more than 0.05 below the policy's, its access rate no more than 0.05 above it.

    python investigations/learner_vs_optimum.py --runs OUT [--preset paper]
    python investigations/learner_vs_optimum.py --seeds 0,1,2 --uc 1,2,3 [--preset paper] [--steps-scale 1]
    python investigations/learner_vs_optimum.py --keys [--uc 1,2,3]

``--runs OUT``: a ``reproduce_all.py`` or ``bench_fidelity.py --out`` folder
(``OUT/uc<N>-<preset>/seed<S>/``); every run's test world is redrawn from its ``run.json`` and
checked against its ``requests.csv`` (the same τ and SafeTail's own rewards) before the policy
is measured on it. ``--seeds``: the policy alone, on the test worlds runs of those seeds would
face (nothing is run). ``--keys``: each key the policy could take, fitted on the first half of
the world-calibration seeds and scored on the other half (why the default key). About 5 s per
use case on 2 cores, plus reading the runs.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from yafs_safetail.cli import ArgumentParser, distinct_int_list, positive_float, run_cli
from yafs_safetail.edge.published import USE_CASES

#: At least two episodes of 256 requests per fit world (the load trace restarts every episode).
MIN_FIT_STEPS = 512


def _fit_steps(text: str) -> int:
    import argparse

    try:
        steps = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if steps < MIN_FIT_STEPS:
        raise argparse.ArgumentTypeError(f"expected at least {MIN_FIT_STEPS} (two episodes), got {steps}")
    return steps


def _use_cases(text: str) -> tuple[int, ...]:
    import argparse

    values = distinct_int_list(text)
    unknown = [v for v in values if v not in USE_CASES]
    if unknown:
        raise argparse.ArgumentTypeError(f"use case {unknown[0]} unknown; valid: "
                                         f"{', '.join(map(str, sorted(USE_CASES)))}")
    return values


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def comparison_table(comparisons: Sequence) -> list[str]:
    """The markdown table of :func:`method_optimum.compare`'s rows, then one line per use case
    on the policy's servers and the claims about them."""
    from yafs_safetail.runs import method_optimum as mo

    lines = [
        "| use case | seeds | SafeTail's zero share | most zeros' | gap | within "
        f"{mo.ZERO_SHARE_MARGIN:g} | SafeTail's access | most zeros' | gap | at most +{mo.ACCESS_MARGIN:g} |",
        "|---|---|---|---|---|---|---|---|---|---|"]
    for row in comparisons:
        lines.append(
            f"| UC{row.use_case} | {len(row.seeds)} | {row.safetail_zero_share:.3f} | "
            f"{row.optimum.zero_share:.3f} | {row.zero_share_gap:+.3f} | {_yes(row.zero_share_met)} | "
            f"{row.safetail_access_rate:.3f} | {row.optimum.access_rate:.3f} | {row.access_gap:+.3f} | "
            f"{_yes(row.access_met)} |")
    lines.append("")
    lines += [policy_line(row.optimum) for row in comparisons]
    return lines


def policy_line(optimum) -> str:
    """One line: the policy's servers and whether it makes each server claim hold."""
    from yafs_safetail.runs import method_optimum as mo

    low, high = optimum.window_range
    seeds = len(optimum.seeds)
    claims = "; ".join(f"{key} holds in {round(optimum.claim_share(key) * seeds)} of {seeds} seeds "
                       f"({optimum.claim_figure(key)})" for key in mo.server_claims(optimum.use_case))
    return (f"UC{optimum.use_case} most zeros (keyed on {optimum.key}): zero share "
            f"{optimum.zero_share:.3f}, {optimum.mean_servers:.2f} servers per request, access "
            f"{optimum.access_rate:.3f}, β-window means {low:.2f}–{high:.2f}"
            + (f"; {claims}" if claims else ""))


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="learner_vs_optimum.py", description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--runs", type=Path, help="a reproduce_all.py / bench_fidelity.py --out folder")
    mode.add_argument("--seeds", type=distinct_int_list,
                      help="the policy alone on these seeds' test worlds (nothing is run)")
    mode.add_argument("--keys", action="store_true",
                      help="each key's zero share on world-calibration seeds it was not fitted on")
    parser.add_argument("--uc", type=_use_cases, default=tuple(sorted(USE_CASES)),
                        help="use cases, comma-separated (with --seeds or --keys; default all)")
    parser.add_argument("--preset", default="paper", help="the runs' preset (default paper)")
    parser.add_argument("--steps-scale", type=positive_float, default=1.0,
                        help="with --seeds: the runs' --steps-scale (their test length; default 1)")
    parser.add_argument("--key", default=None, help="what the policy is keyed on (default: the "
                        "module's DEFAULT_KEY, loads+input+uplink)")
    parser.add_argument("--fit-seeds", type=distinct_int_list, default=None,
                        help="the seeds the policy is fitted on (default: seed_sets.json's world_calibration)")
    parser.add_argument("--fit-steps", type=_fit_steps, default=None,
                        help="requests per fit seed (default 20000)")
    args = parser.parse_args(argv)

    from yafs_safetail.runs import method_optimum as mo
    from yafs_safetail.runs import most_zeros as mz

    key = args.key or mz.DEFAULT_KEY
    if key not in mz.KEYS:
        parser.error(f"--key: expected one of {', '.join(mz.KEYS)}, got {key!r}")
    fit_steps = args.fit_steps or mz.FIT_STEPS
    if args.runs is not None:
        comparisons = mo.compare(mo.run_folders(args.runs, args.preset), key, args.fit_seeds, fit_steps)
        print("\n".join(comparison_table(comparisons)))
        return 0
    if args.keys:
        from yafs_safetail.edge.calibration import seed_set

        seeds = list(args.fit_seeds or seed_set("world_calibration"))
        if len(seeds) < 2:
            parser.error("--keys: expected at least two fit seeds (half to fit, half to score)")
        half = len(seeds) // 2
        print(f"fitted on seeds {seeds[:half]}, scored on {seeds[half:]}, {fit_steps} requests each")
        print("| use case | key | zero share | access |")
        print("|---|---|---|---|")
        for use_case in args.uc:
            shares = mo.key_zero_shares(use_case, seeds[:half], seeds[half:], fit_steps, args.preset)
            for name, (zero, access) in shares.items():
                print(f"| UC{use_case} | {name} | {zero:.3f} | {access:.3f} |")
        return 0
    for use_case in args.uc:
        optimum = mo.optimum_for_seeds(use_case, args.seeds, preset=args.preset,
                                       steps_scale=args.steps_scale, key=key,
                                       fit_seeds=args.fit_seeds, fit_steps=fit_steps)
        print(policy_line(optimum))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
