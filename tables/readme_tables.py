"""Write, or check, the README's tables of figures from the commands that make them.

Each table sits in README.md between ``<!-- readme_tables: NAME -->`` and
``<!-- /readme_tables -->``; this script renders it anew:

    first-run   use case 1 as ``python experiments/run_usecase.py --uc 1`` runs it (the default:
                preset paper, seed 0, full budget); about 10-25 s
    scorecard   the committed ``docs/scorecard.json`` (``python benchmarks/bench_fidelity.py
                --seeds 7400,...,7404 --out OUT``, then ``--from OUT --write docs/scorecard.json``:
                seed_sets.json's method_held_out); reads the file, runs nothing
    least-loaded  ``python tables/least_loaded.py``: SafeTail beside the least-loaded servers
                of all five on seeds 7400-7404; about 5 minutes
    timing      ``python benchmarks/bench_first_answer.py --runs 3``; about 2 minutes, and noisy:
                written, never checked

Usage::

    python tables/readme_tables.py --check                   # the first-run table (CI does)
    python tables/readme_tables.py --check --only first-run,scorecard
    python tables/readme_tables.py --write --only first-run,scorecard,timing

``--check`` exits 1 and names every table that differs from a fresh run (the scorecard: from
the committed file); ``--write`` replaces the tables in README.md. The figures need the lock's library versions (``constraints.txt``):
under others SafeTail's row may differ (docs/results.md, "Versions").
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

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
              f"{summary.loc['Oracle', 'mean_n_selected']:.0f}. " + tails_sentence(summary)]
    return "\n".join(lines) + "\n"


def tails_sentence(summary: Any) -> str:
    """How SafeTail's p90, p95 and p99 compare with every x = 1, 2 and 3 baseline of a run's
    summary (indexed by method): the smallest speed-up against each x, or where it is slower."""
    from yafs_safetail.methods.registry import parse_method

    copies = {1: "those that send each request to one server", 2: "those that send it to two",
              3: "those that send it to three"}
    parts, slower = [], []
    for x, words in copies.items():
        baselines = [m for m in summary.index if m not in ("SafeTail", "Oracle")
                     and parse_method(m)[1] == x]
        ratios = {(m, p): summary.loc[m, f"p{p}_s"] / summary.loc["SafeTail", f"p{p}_s"]
                  for m in baselines for p in (90, 95, 99)}
        if not ratios:
            continue
        (method, percentile), least = min(ratios.items(), key=lambda item: item[1])
        if least > 1.0:
            parts.append(f"{least:.2f}× {words}")
        else:
            slower.append(f"{method} at p{percentile} ({1 / least:.2f}×)")
    if not slower:
        return ("At p90, p95 and p99 it is faster than every baseline, by at least "
                + ", ".join(parts[:-1]) + f" and {parts[-1]}.")
    return ("At p90, p95 and p99 it is slower than " + ", ".join(slower)
            + (f"; faster by {', '.join(parts)}." if parts else "."))


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


#: The committed scorecard the README renders: ``bench_fidelity.py --from OUT --write`` writes it.
SCORECARD_FILE = REPOSITORY / "docs" / "scorecard.json"
#: The seeds it must be measured on: the held-out set added before issue 48's default ran
#: (seed_sets.json's ``method_held_out``), reported once.
SCORECARD_SEED_SET = "method_held_out"
#: A claim's plain statement: its text up to the project's reading, in parentheses.
_READING = " ("
#: ``bench_fidelity.py``'s verdict for a goal the method's own training target cannot reach.
NOT_REACHABLE = "not reachable by the method here"


def _seeds_text(seeds: Sequence[int]) -> str:
    """``7400–7404`` for consecutive seeds, else ``0, 3, 5``."""
    ordered = sorted(seeds)
    if len(ordered) > 2 and ordered == list(range(ordered[0], ordered[-1] + 1)):
        return f"{ordered[0]}–{ordered[-1]}"
    return ", ".join(map(str, ordered))


def _per_use_case(values: Mapping[str, str]) -> str:
    return " / ".join(values[uc] for uc in sorted(values, key=int))


def scorecard_block(card: Mapping[str, Any]) -> str:
    """The README's scorecard, in plain words, from the committed scorecard (``bench_fidelity.py
    --write``'s JSON): one row per goal with what was measured and the verdict, then the
    claims out of reach and a note on how to read it.

    Raises:
        KeyError: a scorecard without a goal this table shows (written by an older benchmark).
    """
    goals = card["goals"]
    ratios, claims = goals["ratios"], goals["reachable_claims"]
    low, high, total = ratios["any_policy_at_most"]
    ceiling = f"{low}" if low == high else f"{low}–{high}"
    calibration, held_out = ratios["calibration"], ratios["held_out"]
    use_cases = card["use_cases"]
    access = goals["access"]["measured"]
    access_text = {uc: f"{row['measured']:.2f}" + (
        f" (its training target's best: {row['most_zeros']:.2f})" if row["verdict"] == NOT_REACHABLE
        else "") for uc, row in access.items()}
    tails, tails_x123 = goals["uc1_tails"], goals["uc1_tails_x123"]
    rows = [
        ("goal", "measured", "verdict"),
        (f"The paper's {ratios['of']} published speed-up ratios reproduced within ±20% (goal: at "
         f"least {ratios['goal'].split()[-1]}; in this world no policy could reproduce more than "
         f"{ceiling} together)",
         f"{ratios['measured']}: {held_out[0]} of the {held_out[1]} nothing was fitted to, "
         f"{calibration[0]} of the {calibration[1]} the simulated world was fitted to",
         ratios["verdict"]),
        (f"The paper's statements besides its ratios that hold, of the {claims['of']} that "
         f"SafeTail's method could make hold here (of {claims['claims_hold'][1]})",
         str(claims["measured"]), claims["verdict"]),
        ("Use case 1: SafeTail's 90th, 95th and 99th percentile latencies below those of every "
         "baseline that sends each request to one server", f"{tails['measured']} of {tails['of']} seeds",
         tails["verdict"]),
        ("Use case 1: the same against every baseline that sends each request to one, two or "
         "three servers", f"{tails_x123['measured']} of {tails_x123['of']} seeds", tails_x123["verdict"]),
        (f"Access rate: the share of the servers SafeTail sends a request to, on average, use "
         f"cases {' / '.join(sorted(access, key=int))} (goal: at most 0.5)",
         _per_use_case(access_text), goals["access"]["verdict"]),
        ("Access rate beside the best that SafeTail's own training target allows, use cases "
         f"{' / '.join(sorted(use_cases, key=int))} (goal: at most 0.05 above)",
         _per_use_case({uc: f"{row['safetail_access_rate']:.2f} vs {row['most_zeros_access_rate']:.2f}"
                        for uc, row in use_cases.items()}), goals["access_vs_method"]["verdict"]),
        ("Share of requests earning the training reward's best value (exactly 0) beside the best "
         f"that target allows, use cases {' / '.join(sorted(use_cases, key=int))} (goal: at most "
         "0.05 below)",
         _per_use_case({uc: f"{row['safetail_zero_share']:.2f} vs {row['most_zeros_zero_share']:.2f}"
                        for uc, row in use_cases.items()}), goals["zero_share"]["verdict"]),
        ("Requests answered on the user's device because every chosen server refused, the most "
         "in any run (goal: at most 0.5%)", f"{100 * goals['fallback']['measured']:.1f}%",
         goals["fallback"]["verdict"]),
    ]
    texts = {f"uc{c.use_case} {c.key}": c.text.split(_READING)[0] for c in _paper_claims()}
    for name in claims["not_reachable_by_any_policy"]:
        rows.append((f"Use case {name[2:].split()[0]}: “{texts[name]}”",
                     "no policy could make it hold in this world", "not reachable by any policy here"))
    for claim in claims["not_reachable_by_the_method"]:
        rows.append((f"Use case {claim['use_case']}: “{claim['text']}”",
                     f"the best policy for SafeTail's own training target: {claim['policy']}",
                     NOT_REACHABLE))
    lines = [f"| {goal} | {value} | {verdict} |" for goal, value, verdict in rows]
    lines.insert(1, "|---|---|---|")
    scale = card.get("steps_scale")
    budget = "" if scale == 1.0 else f" at --steps-scale {scale:g}" if scale else " at mixed budgets"
    lines += ["", (f"Seeds {_seeds_text(card['seeds'])}, preset `{card['preset']}`{budget}, commit "
                   f"{str(card['commit'])[:7]} ([docs/scorecard.json](docs/scorecard.json)). SafeTail's "
                   "training target pays its best reward (exactly 0) when a request goes to one "
                   "server that answers in time, or to all five when none would; “the best that "
                   "target allows” is a policy without a learner that sends each request where "
                   "that reward came most often in other seeds' worlds, measured on the same "
                   "requests (`python investigations/learner_vs_optimum.py`).")]
    return "\n".join(lines) + "\n"


def _paper_claims() -> Sequence[Any]:
    from yafs_safetail.results.paper import PAPER_CLAIMS

    return PAPER_CLAIMS


def read_scorecard(path: Path = SCORECARD_FILE) -> dict[str, Any]:
    """The committed scorecard.

    Raises:
        SystemExit: missing, not JSON, or a placeholder (one line naming the file).
    """
    write = "write it with `python benchmarks/bench_fidelity.py --from OUT --write docs/scorecard.json`"
    if not path.is_file():
        raise SystemExit(f"error: {path}: not found; {write}")
    try:
        card = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise SystemExit(f"error: {path}: cannot be read ({' '.join(str(error).split())})") from None
    if not isinstance(card, dict) or card.get("placeholder") or "goals" not in card:
        raise SystemExit(f"error: {path}: not a scorecard (a placeholder?); {write}")
    return card


def _scorecard() -> str:
    return scorecard_block(read_scorecard())


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


def _least_loaded() -> str:
    with tempfile.TemporaryDirectory(prefix="readme_tables_") as scratch:
        done = subprocess.run([sys.executable, "tables/least_loaded.py", "--out", scratch],
                              cwd=REPOSITORY, stdout=subprocess.PIPE, text=True, check=False)
    if done.returncode:
        raise SystemExit(f"tables/least_loaded.py failed (exit {done.returncode})")
    return done.stdout


RENDERERS: dict[str, Callable[[], str]] = {"first-run": _first_run, "scorecard": _scorecard,
                                           "least-loaded": _least_loaded, "timing": _timing}
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
