"""Write, or check, the README's tables of figures from the commands that make them.

Each table sits in README.md between ``<!-- readme_tables: NAME -->`` and
``<!-- /readme_tables -->``; this script renders it anew:

    first-run   use case 1 as ``python experiments/run_usecase.py --uc 1`` runs it (the default:
                preset paper, seed 0, full budget); about 10-25 s
    scorecard   ``python benchmarks/bench_fidelity.py --seeds 7300,...,7304`` (the held-out set of
                calibration.md's rule 7, seed_sets.json's target_held_out); about 2 minutes
    timing      ``python benchmarks/bench_first_answer.py --runs 3``; about 2 minutes, and noisy:
                written, never checked

Usage::

    python benchmarks/readme_tables.py --check                   # the first-run table (CI does)
    python benchmarks/readme_tables.py --check --only first-run,scorecard
    python benchmarks/readme_tables.py --write --only first-run,scorecard,timing

``--check`` exits 1 and names every table that differs from a fresh run; ``--write`` replaces
the tables in README.md. The figures need the lock's library versions (``constraints.txt``):
under others SafeTail's row may differ (docs/results.md, "Versions").
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
README = REPOSITORY / "README.md"
BLOCK = re.compile(r"(<!-- readme_tables: (?P<name>[a-z-]+) -->\n)(?P<body>.*?)(<!-- /readme_tables -->)",
                   re.DOTALL)
#: The first table's rows: SafeTail and the x = 1 and x = 3 baselines (x = 2 is in summary.md).
FIRST_RUN_METHODS = ("SafeTail", "Oracle", "Rand-1", "Rand-3", "MinLoad-1", "MinLoad-3",
                     "MinProp-1", "MinProp-3")


def first_run_block(results: Path) -> str:
    """The first table and its sentence, from a default use-case-1 run's results folder."""
    import pandas as pd

    summary = pd.read_csv(results / "summary.csv").set_index("method")
    preset = str(summary.loc["SafeTail", "preset"])
    lines = ["| method | median | p90 | p95 | p99 | mean servers | target met | fallbacks |",
             "|---|---|---|---|---|---|---|---|"]
    for method in FIRST_RUN_METHODS:
        row = summary.loc[method]
        name = f"SafeTail (`{preset}`)" if method == "SafeTail" else method
        lines.append(f"| {name} | {row.p50_s:.3f} | {row.p90_s:.3f} | {row.p95_s:.3f} | "
                     f"{row.p99_s:.3f} | {row.mean_n_selected:.2f} | {100 * row.target_met_rate:.1f}% | "
                     f"{100 * row.fallback_rate:.1f}% |")
    p99 = summary["p99_s"]
    safetail = summary.loc["SafeTail"]
    lines += ["", f"SafeTail's p99 is {100 * (p99['SafeTail'] / p99['Oracle'] - 1):.0f}% above "
              f"Oracle's with {safetail.mean_n_selected:.2f} servers per request against Oracle's "
              f"{summary.loc['Oracle', 'mean_n_selected']:.0f}; it is "
              f"{p99['Rand-1'] / p99['SafeTail']:.1f}×, {p99['MinProp-1'] / p99['SafeTail']:.1f}× "
              f"and {p99['MinLoad-1'] / p99['SafeTail']:.2f}× lower than Rand-1's, MinProp-1's and "
              "MinLoad-1's."]
    return "\n".join(lines) + "\n"


def _first_run() -> str:
    from yafs_safetail.commands import run_usecase

    with tempfile.TemporaryDirectory(prefix="readme_tables_") as scratch:
        out = Path(scratch) / "uc1"
        code = run_usecase.main(["--uc", "1", "--no-figures", "--quiet", "--out", str(out)])
        if code:
            raise SystemExit(code)
        return first_run_block(out)


def _script_lines(*argv: str) -> dict[str, str]:
    """A benchmark's ``key=value`` lines (its errors go to this script's stderr)."""
    done = subprocess.run([sys.executable, *argv], cwd=REPOSITORY, stdout=subprocess.PIPE,
                          text=True, check=False)
    if done.returncode:
        raise SystemExit(f"{argv[0]} failed (exit {done.returncode})")
    return dict(line.split("=", 1) for line in done.stdout.splitlines() if "=" in line)


def scorecard_block(figures: dict[str, str]) -> str:
    """The scorecard table from ``bench_fidelity.py``'s lines."""
    ratios, _ = figures["ratios_within_20"].split("/")
    held, held_total = figures["held_out_within_20"].split("/")
    reachable, reachable_total = figures["reachable_claims_hold"].split("/")
    claims_total = figures["claims_hold"].split("/")[1]
    ceiling = figures["any_policy_ratios_at_most"].split("/")[0]
    access = " / ".join(f"{float(figures[f'access_rate_uc{uc}']):.2f}" for uc in (1, 2, 3))
    fallback = float(figures["safetail_fallback_max"])
    below, seeds = figures["uc1_tails_below_x1_seeds"].split("/")
    rows = [
        ("goal", "measured"),
        (f"ratios within ±20% of the paper's 23 (any policy: {ceiling.replace('-', '–')})",
         f"{ratios} (held out: {held} of {held_total})"),
        (f"claims that hold, of the {reachable_total} any policy could hold (of {claims_total})",
         reachable),
        ("SafeTail's mean access rate, UC1 / UC2 / UC3 (goal ≤ 0.5)", access),
        ("SafeTail's fallbacks, the most in any run (goal ≤ 0.5%)", f"{100 * fallback:.1f}%"),
        ("UC1: SafeTail's p90–p99 below every x = 1 baseline's", f"{below} of {seeds} seeds"),
    ]
    lines = [f"| {goal} | {value} |" for goal, value in rows]
    lines.insert(1, "|---|---|")
    return "\n".join(lines) + "\n"


#: The scorecard's seeds: the held-out set nothing had read before calibration.md's rule 7, the
#: default's latest change (seed_sets.json's ``target_held_out``).
SCORECARD_SEEDS = "7300,7301,7302,7303,7304"


def _scorecard() -> str:
    return scorecard_block(_script_lines("benchmarks/bench_fidelity.py", "--seeds", SCORECARD_SEEDS))


TIMED = (("help", "`run_usecase.py --help`"), ("error", "`run_usecase.py --uc 7` (an argument error)"),
         ("quick", "`run_usecase.py --uc 1 --steps-scale 0.02`"),
         ("default", "`run_usecase.py --uc 1` (the default)"))


def timing_block(figures: dict[str, str]) -> str:
    """The wait table from ``bench_first_answer.py``'s lines."""
    lines = ["| command | median wall time |", "|---|---|"]
    lines += [f"| {label} | {float(figures[f'{name}_s']):.2f} s |" for name, label in TIMED]
    return "\n".join(lines) + "\n"


def _timing() -> str:
    return timing_block(_script_lines("benchmarks/bench_first_answer.py", "--runs", "3"))


RENDERERS: dict[str, Callable[[], str]] = {"first-run": _first_run, "scorecard": _scorecard,
                                           "timing": _timing}
#: Timings move with the machine's load: written, never compared.
NEVER_CHECKED = ("timing",)


def readme_blocks(text: str) -> dict[str, str]:
    """Every marked table of the README, by name."""
    return {match["name"]: match["body"] for match in BLOCK.finditer(text)}


def replaced(text: str, name: str, body: str) -> str:
    """The README's text with table ``name`` replaced by ``body``."""
    return BLOCK.sub(lambda m: m.group(1) + body + m.group(4) if m["name"] == name else m.group(0), text)


def _names(text: str) -> tuple[str, ...]:
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    unknown = [name for name in names if name not in RENDERERS]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"unknown table(s) {unknown}; valid: {', '.join(RENDERERS)}")
    return names


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="compare the tables with a fresh run")
    mode.add_argument("--write", action="store_true", help="rewrite the tables in README.md")
    parser.add_argument("--only", type=_names, default=("first-run",),
                        help=f"tables, comma-separated, of {', '.join(RENDERERS)} (default first-run)")
    args = parser.parse_args(argv)
    text = README.read_text(encoding="utf-8")
    blocks = readme_blocks(text)
    missing = [name for name in args.only if name not in blocks]
    if missing:
        print(f"error: {README}: no table marked {missing[0]!r}", file=sys.stderr)
        return 2
    stale = []
    for name in args.only:
        if args.check and name in NEVER_CHECKED:
            print(f"{name}: not checked (timings move with the machine's load)")
            continue
        body = RENDERERS[name]()
        if args.write:
            text = replaced(text, name, body)
        elif body != blocks[name]:
            stale.append(name)
            print(f"{name}: README.md differs from a fresh run; it gives:\n{body}")
        else:
            print(f"{name}: as a fresh run gives")
    if args.write:
        README.write_text(text, encoding="utf-8")
        print(f"written: {', '.join(args.only)} in {README}")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
