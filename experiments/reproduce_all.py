"""Run every use case over several seeds and write one report against the paper's numbers.

    python experiments/reproduce_all.py                          # UC 1-3, seeds 0-4, paper preset
    python experiments/reproduce_all.py --preset paper,paper-literal,tuned --seeds 0,1,2,3,4,5
    python experiments/reproduce_all.py --steps-scale 0.1 --out results/quick
    python experiments/reproduce_all.py --workers 2                # two runs at a time
    python experiments/reproduce_all.py --engine ray               # on Ray (see docs/campaigns.md)
    python experiments/reproduce_all.py --learning-rate 1e-3 --out results/paper-lr1e-3

For every (use case, preset, seed) it runs exactly what ``run_usecase.py`` runs, into
``OUT/uc<N>-<preset>/seed<S>/``. Then ``OUT/REPORT.md`` opens with the fidelity scorecard of
each preset (every ratio and claim the paper publishes against ours over the seeds, calibration
subset and held-out numbers apart; also in ``OUT/fidelity.csv`` and the figure
``OUT/fidelity-<preset>.png``), then what any policy could reach in that world (whether the
paper's statements about each percentile can hold together at all, from Oracle's and the
baselines' latencies and the targets alone; ``OUT/feasibility.csv``,
yafs_safetail/results/feasibility.py), and gives, per use case and preset: the latency table (mean over
seeds and a 95% bootstrap interval), our ratios beside the paper's stated ones with a plain
note where they differ, what the learner did (training rounds, final ε, servers used, target
met, fallbacks) as the first place to look for why, figures across seeds with 95% bands
(``OUT/figures/uc<N>-<preset>-latency-bands`` and ``-servers-bands``, PNG and PDF) and the
figures of the first seed. Every table of the report is also written as LaTeX
(``OUT/tables/*.tex``, listed at the end of REPORT.md). Seeds must be distinct; the scorecard
asks for at least five.

The runs form one campaign (yafs_safetail/runs/campaign.py): rerunning the same command on the
same --out resumes an interrupted reproduction and recomputes no finished run (a run folder
records its run id, a hash of its configuration and the code version); a run that fails is
reported and the others go on (exit status 1, no report). Progress goes to stderr and
``OUT/campaign.log``, each run's state to ``OUT/campaign.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from yafs_safetail import results
from yafs_safetail.cli import (
    ArgumentParser,
    add_verbosity_options,
    configure_verbosity,
    distinct_int_list,
    run_cli,
)
from yafs_safetail.edge.calibration import (
    CalibrationError,
    read_calibration,
    seed_set,
)
from yafs_safetail.edge.published import USE_CASES
from yafs_safetail.figures import FIGURES_DIR
from yafs_safetail.figures_multiseed import (
    LATENCY_BANDS_STEM,
    SERVERS_BANDS_STEM,
    draw_multiseed_figures,
)
from yafs_safetail.methods.safetail.presets import PRESET_NAMES
from yafs_safetail.results import feasibility, fidelity, latex
from yafs_safetail.runs.campaign import add_engine_options, engine_free_command, run_campaign
from yafs_safetail.runs.config import LearnerOverrides, add_options
from yafs_safetail.runs.experiment import ExperimentError
from yafs_safetail.runs.grid import expand
from yafs_safetail.runs.output import refuse_protected

#: Each run's folder under --out.
RUN_FOLDER = "uc{use_case}-{preset}/seed{seed}"

FIGURE_STEMS = (
    ("a", "fig_a_latency_comparison", "latency comparison with target and baselines"),
    ("b", "fig_b_safetail_vs_rand", "SafeTail vs Rand-x"),
    ("c", "fig_c_safetail_vs_minload", "SafeTail vs MinLoad-x"),
    ("d", "fig_d_safetail_vs_minprop", "SafeTail vs MinProp-x"),
    ("e", "fig_e_access_rate", "access rate per average episode"),
    ("f", "fig_f_latency_deviation", "latency deviation per average episode"),
    ("g", "fig_g_abs_reward", "|reward| per average episode"),
)


def _presets(text: str) -> tuple[str, ...]:
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    unknown = [n for n in names if n not in PRESET_NAMES]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"unknown preset(s) {unknown}; valid: {', '.join(PRESET_NAMES)}")
    return names


def _calibration_seed_note(seeds: Sequence[int]) -> str:
    """A warning when a report seed is one the world's fit or the learning-rate rule chose on."""
    try:
        used = (set(read_calibration()["provenance"].get("seeds", []))
                | set(seed_set("world_calibration")) | set(seed_set("learner_calibration")))
    except CalibrationError:
        return ""
    shared = sorted(used & set(seeds))
    if not shared:
        return " None of these seeds was used by the calibration."
    return (f" Seeds {shared} were used by the calibration (yafs_safetail/edge/seed_sets.json): "
            "on them the numbers are not independent of the fit and the learning-rate rule.")


def _learner_diagnostics(folders: Sequence[Path]) -> pd.DataFrame:
    """What SafeTail did in each seed: the first place to look when a ratio differs.

    Display strings, one row per seed (REPORT.md and its LaTeX twin are made from it).
    """
    header = ["seed", "training rounds", "final ε", "SafeTail servers used (test: mean, min-max)",
              "target met (test)", "fallbacks (test)"]
    rows = []
    for folder in folders:
        run = results.read_run_json(folder)
        summary = results.read_summary_csv(folder)
        row = summary[summary["method"] == results.SAFETAIL].iloc[0]
        rows.append([
            str(run.seed), str(run.extra.get("training_rounds", "?")),
            f"{float(run.extra.get('final_epsilon', float('nan'))):.3f}",
            f"{row['mean_n_selected']:.2f} ({int(row['min_n_selected'])}-{int(row['max_n_selected'])})",
            f"{row['target_met_rate']:.1%}", f"{row['fallback_rate']:.1%}",
        ])
    return pd.DataFrame(rows, columns=header, dtype=object)


#: A baseline that falls back on more than this share of requests has fallback-set tails.
FALLBACK_NOTE_RATE = 0.01


def _why_lines(folders: Sequence[Path]) -> list[str]:
    """Reasons, read off the runs themselves, why ratios may differ from the paper's."""
    summaries = [results.read_summary_csv(f).set_index("method") for f in folders]
    runs = [results.read_run_json(f) for f in folders]
    mean = pd.concat(summaries).groupby(level=0).mean(numeric_only=True)
    lines = []
    epsilon = [float(r.extra.get("final_epsilon", float("nan"))) for r in runs]
    if runs[0].train_steps and min(epsilon) > 0.5:
        lines.append(
            f"- SafeTail's ε after training is {min(epsilon):.4f}–{max(epsilon):.4f}: with this "
            "preset the training phase is almost pure exploration, so the tested policy is close "
            "to the untrained network's argmax (docs/deviations.md D1)."
        )
    safetail = mean.loc[results.SAFETAIL]
    lines.append(
        f"- SafeTail sends {safetail['mean_n_selected']:.2f} copies per request on average "
        f"and meets the target on {safetail['target_met_rate']:.0%} "
        f"of requests; Oracle meets it on {mean.loc[results.ORACLE, 'target_met_rate']:.0%}."
    )
    fallback_s = runs[0].extra.get("fallback_latency_s")
    falling_back = [
        f"{method} {row['fallback_rate']:.1%} (from about p{100 * (1 - row['fallback_rate']):.0f})"
        for method, row in mean.loc[results.sort_methods(mean.index)].iterrows()
        if method != results.SAFETAIL and row["fallback_rate"] > FALLBACK_NOTE_RATE
    ]
    if falling_back:
        lines.append(
            f"- Baselines that fall back to the on-device version ({fallback_s} s) when every "
            f"chosen server is full: {', '.join(falling_back)}. Their percentiles from there on "
            "are the fallback latency, so ratios against them there measure the fallback model "
            "(docs/deviations.md D5), not edge latency."
        )
    if safetail["fallback_rate"] > FALLBACK_NOTE_RATE:
        lines.append(
            f"- SafeTail itself falls back on {safetail['fallback_rate']:.1%} of requests, which "
            "sets its own p99."
        )
    return lines


#: Every table REPORT.md shows, as a LaTeX file under OUT/tables/ (results/latex.py).
TABLE_NAMES = {
    "latency": "latency-uc{use_case}-{preset}",
    "ratios": "ratios-uc{use_case}-{preset}",
    "learner": "learner-uc{use_case}-{preset}",
    "scorecard": "fidelity-{preset}-{part}",
    "feasibility": "feasibility-{preset}",
}


def _tex_pointer(*names: str) -> str:
    """REPORT.md's line naming a table's LaTeX file(s) (OUT/tables/ is beside REPORT.md)."""
    links = [f"[`{latex.TABLES_DIR}/{n}{latex.TABLE_SUFFIX}`]({latex.TABLES_DIR}/{n}{latex.TABLE_SUFFIX})"
             for n in names]
    return "LaTeX: " + ", ".join(links)


def _section(use_case: int, preset: str, folders: Sequence[Path],
             report_dir: Path) -> tuple[list[str], dict[str, str]]:
    """One use case and preset: REPORT.md's lines and the LaTeX tables (name -> source)."""
    run = results.read_run_json(folders[0])
    stats = results.aggregate_summaries(folders)
    ratios = results.aggregate_speedups(folders)
    diagnostics = _learner_diagnostics(folders)
    names = {key: TABLE_NAMES[key].format(use_case=use_case, preset=preset)
             for key in ("latency", "ratios", "learner")}
    tables = {
        names["latency"]: latex.latency_latex(stats, use_case=use_case,
                                              use_case_name=run.use_case_name, preset=preset),
        names["ratios"]: latex.comparison_latex(ratios, use_case=use_case, preset=preset),
        names["learner"]: latex.table_latex(
            diagnostics, label=f"tab:learner-uc{use_case}-{preset}", column_format="rrrrrr",
            caption=f"Use case {use_case}, preset {preset}: what SafeTail did in each seed "
                    "(training rounds, final ε, servers per request, target met and fallbacks "
                    "in the test phase)."),
    }
    # The bands over seeds go beside the report (OUT/figures), not into a run's folder.
    draw_multiseed_figures(folders, report_dir / FIGURES_DIR)
    figures_dir = folders[0] / FIGURES_DIR
    lines = [
        f"## Use case {use_case}: {run.use_case_name} — preset `{preset}`",
        "",
        f"{len(folders)} seed(s) ({', '.join(str(results.read_run_json(f).seed) for f in folders)}); "
        f"{run.train_steps} training steps, {run.test_steps} test steps per method; "
        f"topology `{run.topology}`.",
        "",
        "### Latency (test phase)",
        "",
        results.aggregate_markdown(stats).rstrip("\n"),
        "",
        _tex_pointer(names["latency"]),
        "",
        "### Our ratios beside the paper's",
        "",
        results.comparison_markdown(ratios).rstrip("\n"),
        "",
        _tex_pointer(names["ratios"]),
        "",
        "### What SafeTail did",
        "",
        *results.frame_markdown(diagnostics),
        "",
        _tex_pointer(names["learner"]),
        "",
        "### Why our ratios may differ (read off these runs)",
        "",
        *_why_lines(folders),
        "",
        "### Across seeds (mean, shaded 95% bootstrap interval over seeds)",
        "",
    ]
    for stem, caption in ((LATENCY_BANDS_STEM, "latency percentiles per method"),
                          (SERVERS_BANDS_STEM, "SafeTail's servers per request over time")):
        png = Path(FIGURES_DIR) / f"{stem.format(use_case=use_case, preset=preset)}.png"
        lines += [f"{caption}: ![{caption}]({png}) (also `.pdf`)", ""]
    lines += [f"### Figures (seed {run.seed})", ""]
    for panel, stem, caption in FIGURE_STEMS:
        png = figures_dir / f"{stem}.png"
        if png.is_file():
            lines.append(f"({panel}) {caption}: ![{caption}]({os.path.relpath(png, report_dir)})")
            lines.append("")
    return lines, tables


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="reproduce_all.py", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=distinct_int_list, default=USE_CASES, help="use cases (default: all)")
    parser.add_argument("--seeds", type=distinct_int_list, default=(0, 1, 2, 3, 4),
                        help="distinct seeds (default 0,1,2,3,4; the scorecard wants five or more)")
    parser.add_argument("--preset", type=_presets, default=("paper",),
                        help="preset(s), comma-separated (default paper)")
    parser.add_argument("--out", type=Path, default=Path("results/reproduce"),
                        help="output folder (default results/reproduce)")
    # The settings every run shares, each declared once in runs.config (its type, check and
    # default); the help says what they mean for the whole reproduction.
    add_options(parser, only=("steps_scale", "target_compute"),
                steps_scale={"help": "fraction of each preset's steps (default 1)"},
                target_compute={"help": "C(s_j) of Eq. 4 for every run (default: each preset world's; "
                                        "docs/deviations.md D11)"})
    add_options(parser, LearnerOverrides,  # every learner hyperparameter a run may override
                learning_rate={"help": "Adam's learning rate for every run instead of each preset's (the "
                                       "report then says these are not the presets' results)"})
    add_options(parser, only=("figures",), figures={"help": "skip the per-run figures"})
    parser.add_argument("--overwrite", action="store_true",
                        help="replace run folders in --out that hold another configuration")
    add_engine_options(parser)
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    bad = [uc for uc in args.uc if uc not in USE_CASES]
    if bad:
        raise ExperimentError(f"--uc: unknown use case(s) {bad}; valid: 1, 2, 3")

    command = engine_free_command("experiments/reproduce_all.py", sys.argv[1:] if argv is None else argv)
    refuse_protected(args.out)
    # Every (use case, preset, seed) is one run of a campaign: resumable, in parallel with
    # --workers, each run's folder where it always was.
    base = {"steps_scale": args.steps_scale, "figures": args.figures}
    overridable = ("target_compute", *(item.name for item in dataclasses.fields(LearnerOverrides)))
    base.update({name: getattr(args, name) for name in overridable if getattr(args, name) is not None})
    specs = expand(base,
                   {"use_case": list(args.uc), "preset": list(args.preset), "seed": list(args.seeds)},
                   name=RUN_FOLDER, source="reproduce_all.py")
    outcome = run_campaign(specs, args.out, engine=args.engine, workers=args.workers,
                           ray_address=args.ray_address, command=command, overwrite=args.overwrite)
    if outcome.failed:
        print(f"error: {outcome.failed} run(s) failed (see above); no report written; rerun the "
              "same command to retry them (finished runs are kept)", file=sys.stderr)
        return 1
    sections: list[str] = []
    section_tables: dict[str, str] = {}
    speedups = []
    differences: list[str] = []  # how any run's setting departs from the paper's
    summaries: dict[str, dict[int, list[pd.DataFrame]]] = {p: {} for p in args.preset}
    worlds: dict[str, list[feasibility.WorldRun]] = {p: [] for p in args.preset}
    for use_case in args.uc:
        for preset in args.preset:
            folders = [args.out / RUN_FOLDER.format(use_case=use_case, preset=preset, seed=seed)
                       for seed in args.seeds]
            lines, tables = _section(use_case, preset, folders, args.out)
            sections += lines
            section_tables.update(tables)
            summaries[preset][use_case] = [results.read_summary_csv(f) for f in folders]
            for folder in folders:
                differences += [d for d in results.setting_differences(
                    results.read_run_json(folder / results.RUN_FILE)) if d not in differences]
            worlds[preset] += [feasibility.read_world_run(f) for f in folders]
            table = results.aggregate_speedups(folders)
            table.insert(1, "preset", preset)
            speedups.append(table)

    header = [
        "# SafeTail reproduction report",
        "",
        f"Produced by `{command}`. Every number below comes from the run folders beside this "
        "file; rerun the command to reproduce it (same seeds, identical summaries).",
        "",
    ]
    if differences:
        header += ["**Closeness to the paper: not scored.** These runs are not in the paper's "
                   f"setting ({'; '.join(differences)}): the scorecard below sets them beside the "
                   "paper's numbers for information, not as a reproduction.", ""]
    if args.learning_rate is not None:
        header += [f"**Every run trained SafeTail at learning rate {args.learning_rate:g} "
                   "(`--learning-rate`) instead of its preset's: where this report names a "
                   "preset, it means that preset with this learning rate, not the preset's own "
                   "results.**", ""]
    header += [
        "How to read the ratios: a speed-up is a latency ratio, > 1 means the first-named method "
        "is faster. \"consistent\" means the paper's number lies inside our 95% interval over "
        "seeds; \"differs\" says in which way. Our traces are synthetic, generated from the "
        "published statistics (traces/README.md), and every choice where the paper is silent "
        "is documented (docs/edge_model.md, docs/policy.md, docs/deviations.md), so differences "
        "in size are expected; the section \"What SafeTail did\" shows, per seed, whether the "
        "learner trained, how many servers it ended up using and how often it met the target.",
        "",
    ]
    scorecard_lines, cards, checks = [], [], []
    scorecard_tables: dict[str, str] = {}
    for preset in args.preset:
        card = fidelity.scorecard(summaries[preset])
        card.insert(0, "preset", preset)
        cards.append(card)
        fidelity.draw_scorecard(card, args.out / f"{fidelity.FIDELITY_FIGURE}-{preset}")
        few = (f" Only {len(args.seeds)} seed(s): the scorecard is meant for five or more."
               if len(args.seeds) < 5 else "")
        few += _calibration_seed_note(args.seeds)
        scorecard_lines += [
            f"## Fidelity scorecard — preset `{preset}`", "",
            f"Seeds {', '.join(map(str, args.seeds))}; use cases {', '.join(map(str, args.uc))}.{few} "
            f"Figure: ![paper vs ours](fidelity-{preset}.png)", "",
            fidelity.scorecard_markdown(card).rstrip("\n"), "",
        ]
        card_tables = {
            TABLE_NAMES["scorecard"].format(preset=preset, part=part.replace("_", "-")): tex
            for part, tex in latex.scorecard_latex(card, preset=preset).items()}
        scorecard_tables.update(card_tables)
        scorecard_lines += [_tex_pointer(*card_tables), ""]
        checked = feasibility.check_all(worlds[preset])
        checked.insert(0, "preset", preset)
        checks.append(checked)
        name = TABLE_NAMES["feasibility"].format(preset=preset)
        scorecard_tables[name] = latex.table_latex(
            feasibility.feasibility_display(checked),
            caption=f"What any policy could reach in this world, preset {preset}: the paper's "
                    "statements about each percentile as intervals on SafeTail's latency.",
            label=f"tab:feasibility-{preset}")
        scorecard_lines += [
            f"## What any policy could reach in this world — preset `{preset}`", "",
            feasibility.ceiling_line(worlds[preset]), "",
            feasibility.feasibility_markdown(checked).rstrip("\n"), "",
            _tex_pointer(name), "",
        ]
    results.write_text_atomic(args.out / fidelity.FIDELITY_FILE,
                              pd.concat(cards, ignore_index=True).to_csv(index=False))
    results.write_text_atomic(args.out / feasibility.FEASIBILITY_FILE,
                              pd.concat(checks, ignore_index=True).to_csv(index=False))
    # Tables in the order REPORT.md shows them: scorecards first, then each use case.
    table_paths = latex.write_tables(args.out, {**scorecard_tables, **section_tables})
    report = "\n".join(header + scorecard_lines + sections
                       + latex.tables_markdown(table_paths, args.out) + [""])
    results.write_text_atomic(args.out / "REPORT.md", report)
    all_speedups = pd.concat(speedups, ignore_index=True)
    results.write_text_atomic(args.out / "speedups.csv", all_speedups.to_csv(index=False))
    print(f"report: {args.out / 'REPORT.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
