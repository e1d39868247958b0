"""REPORT.md of a reproduction: every use case and preset over several seeds, against the
paper's numbers, assembled from the run folders a campaign wrote (``yafs-safetail reproduce``,
yafs_safetail/commands/reproduce_all.py, runs them; this module only reads them).

``OUT/REPORT.md`` opens with the fidelity scorecard of each preset (``OUT/fidelity.csv``, the
figure ``OUT/fidelity-<preset>.png``), then what any policy could reach in that world
(``OUT/feasibility.csv``), then per use case and preset the latency table over seeds, our ratios
beside the paper's, what the learner did, why the ratios may differ, the figures across seeds
(``OUT/figures/``) and the first seed's figures. Every table is also written as LaTeX under
``OUT/tables/``; ``OUT/speedups.csv`` holds every ratio.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from yafs_safetail import results
from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS
from yafs_safetail.edge.calibration import CalibrationError, read_calibration, seed_set
from yafs_safetail.results import feasibility, fidelity, latex, seed_tables
from yafs_safetail.results.figures.multiseed import (
    LATENCY_BANDS_STEM,
    SERVERS_BANDS_STEM,
    draw_multiseed_figures,
)
from yafs_safetail.results.figures.run_figures import FIGURE_STEMS, FIGURES_DIR
from yafs_safetail.results.over_seeds import metrics_over_seeds, speedups_over_seeds
from yafs_safetail.results.report import reading_line

#: Each run's folder under the reproduction's folder.
RUN_FOLDER = "uc{use_case}-{preset}/seed{seed}"
REPORT_FILE = "REPORT.md"
SPEEDUPS_FILE = "speedups.csv"
#: The users' own policies (``--method``): their latency and speed-ups over seeds, one row per
#: use case, preset, method and quantity (written only when there are such policies).
METHODS_FILE = "methods.csv"
#: The first seed's figures REPORT.md shows, by panel (run_figures.FIGURE_STEMS names their files).
FIGURE_CAPTIONS = {
    "a": "latency comparison with target and baselines",
    "b": "SafeTail vs Rand-x",
    "c": "SafeTail vs MinLoad-x",
    "d": "SafeTail vs MinProp-x",
    "e": "access rate per average episode",
    "f": "latency deviation per average episode",
    "g": "|reward| per average episode",
}


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
    "methods": "methods-uc{use_case}-{preset}",
    "methods_ratios": "methods-ratios-uc{use_case}-{preset}",
    "scorecard": "fidelity-{preset}-{part}",
    "feasibility": "feasibility-{preset}",
}


def _tex_pointer(*names: str) -> str:
    """REPORT.md's line naming a table's LaTeX file(s) (OUT/tables/ is beside REPORT.md)."""
    links = [f"[`{latex.TABLES_DIR}/{n}{latex.TABLE_SUFFIX}`]({latex.TABLES_DIR}/{n}{latex.TABLE_SUFFIX})"
             for n in names]
    return "LaTeX: " + ", ".join(links)


def _table_block(title: str, markdown: str, tex_name: str) -> list[str]:
    """A REPORT.md subsection: its title, the table and where its LaTeX twin is."""
    return [f"### {title}", "", markdown.rstrip("\n"), "", _tex_pointer(tex_name), ""]


def _users_methods(use_case: int, preset: str, folders: Sequence[Path]
                   ) -> tuple[list[str], dict[str, str], pd.DataFrame]:
    """The users' own policies (``--method``) beside SafeTail and Oracle over the seeds:
    REPORT.md's lines, the LaTeX tables (name -> source) and ``methods.csv``'s rows (nothing
    at all when the runs hold no such policy)."""
    summaries = [results.read_summary_csv(f) for f in folders]
    theirs = seed_tables.user_methods(m for summary in summaries for m in summary["method"])
    if not theirs:
        return [], {}, pd.DataFrame()
    stats = metrics_over_seeds(summaries, methods=[*seed_tables.REFERENCES, *theirs])
    ratios = speedups_over_seeds(summaries, theirs, seed_tables.REFERENCES)
    latency, speedups = seed_tables.latency_table(stats), seed_tables.speedup_table(ratios)
    names = {key: TABLE_NAMES[key].format(use_case=use_case, preset=preset)
             for key in ("methods", "methods_ratios")}
    where = f"Use case {use_case}, preset {preset}"
    tables = {
        names["methods"]: latex.table_latex(
            latency, label=f"tab:{names['methods']}",
            caption=f"{where}: your methods beside SafeTail and Oracle. {seed_tables.LATENCY_NOTE}"),
        names["methods_ratios"]: latex.table_latex(
            speedups, label=f"tab:{names['methods_ratios']}",
            caption=f"{where}: your methods' speed-ups over SafeTail and Oracle. {seed_tables.SPEEDUP_NOTE}"),
    }
    lines = [
        *_table_block("Your methods beside SafeTail and Oracle",
                      seed_tables.markdown(seed_tables.LATENCY_NOTE, latency), names["methods"]),
        *_table_block("Your methods' speed-ups over SafeTail and Oracle",
                      seed_tables.markdown(seed_tables.SPEEDUP_NOTE, speedups), names["methods_ratios"]),
    ]
    ratios = ratios.assign(metric=[f"speedup_over_{r}_p{p}" for r, p in zip(ratios["reference"],
                                                                           ratios["percentile"], strict=True)])
    rows = pd.concat([stats[stats["method"].isin(theirs)], ratios[list(stats.columns)]], ignore_index=True)
    rows.insert(0, "use_case", use_case)
    rows.insert(1, "preset", preset)
    return lines, tables, rows


def _section(use_case: int, preset: str, folders: Sequence[Path], report_dir: Path,
             figure_formats: Sequence[str]) -> tuple[list[str], dict[str, str], pd.DataFrame]:
    """One use case and preset: REPORT.md's lines, the LaTeX tables (name -> source) and the
    users' methods' rows of ``methods.csv``."""
    run = results.read_run_json(folders[0])
    stats = results.aggregate_summaries(folders)
    ratios = results.aggregate_speedups(folders)
    diagnostics = _learner_diagnostics(folders)
    theirs_lines, theirs_tables, theirs_rows = _users_methods(use_case, preset, folders)
    names = {key: TABLE_NAMES[key].format(use_case=use_case, preset=preset)
             for key in ("latency", "ratios", "learner")}
    tables = {
        names["latency"]: latex.latency_latex(stats, use_case=use_case,
                                              use_case_name=run.use_case_name, preset=preset),
        names["ratios"]: latex.comparison_latex(ratios, use_case=use_case, preset=preset),
        **theirs_tables,  # in the order REPORT.md shows them
        names["learner"]: latex.table_latex(
            diagnostics, label=f"tab:learner-uc{use_case}-{preset}", column_format="rrrrrr",
            caption=f"Use case {use_case}, preset {preset}: what SafeTail did in each seed "
                    "(training rounds, final ε, servers per request, target met and fallbacks "
                    "in the test phase)."),
    }
    # The bands over seeds go beside the report (OUT/figures), not into a run's folder.
    draw_multiseed_figures(folders, report_dir / FIGURES_DIR, figure_formats)
    figures_dir = folders[0] / FIGURES_DIR
    lines = [
        f"## Use case {use_case}: {run.use_case_name} — preset `{preset}`",
        "",
        f"{len(folders)} seed(s) ({', '.join(str(results.read_run_json(f).seed) for f in folders)}); "
        f"{run.train_steps} training steps, {run.test_steps} test steps per method; "
        f"topology `{run.topology}`.{reading_line(run.baseline_reading)}",
        "",
        *_table_block("Latency (test phase)", results.aggregate_markdown(stats), names["latency"]),
        *_table_block("Our ratios beside the paper's", results.comparison_markdown(ratios),
                      names["ratios"]),
        *theirs_lines,
        *_table_block("What SafeTail did", "\n".join(results.frame_markdown(diagnostics)),
                      names["learner"]),
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
        also = " (also `.pdf`)" if "pdf" in figure_formats else ""
        lines += [f"{caption}: ![{caption}]({png}){also}", ""]
    lines += [f"### Figures (seed {run.seed})", ""]
    for panel, caption in FIGURE_CAPTIONS.items():
        png = figures_dir / f"{FIGURE_STEMS[panel]}.png"
        if png.is_file():
            lines.append(f"({panel}) {caption}: ![{caption}]({os.path.relpath(png, report_dir)})")
            lines.append("")
    return lines, tables, theirs_rows


def _header(command: str, differences: Sequence[str], learning_rate: float | None) -> list[str]:
    """REPORT.md's opening: where it comes from, whether it is the paper's setting, how to read it."""
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
    if learning_rate is not None:
        header += [f"**Every run trained SafeTail at learning rate {learning_rate:g} "
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
    return header


def _scorecards(out: Path, use_cases: Sequence[int], presets: Sequence[str], seeds: Sequence[int],
                summaries: dict[str, dict[int, list[pd.DataFrame]]],
                worlds: dict[str, list[feasibility.WorldRun]], figure_formats: Sequence[str],
                ) -> tuple[list[str], dict[str, str]]:
    """Each preset's fidelity scorecard and feasibility check: REPORT.md's lines and LaTeX
    tables (name -> source); writes fidelity.csv, feasibility.csv and the scorecard figures."""
    scorecard_lines, cards, checks = [], [], []
    scorecard_tables: dict[str, str] = {}
    for preset in presets:
        card = fidelity.scorecard(summaries[preset])
        card.insert(0, "preset", preset)
        cards.append(card)
        fidelity.draw_scorecard(card, out / f"{fidelity.FIDELITY_FIGURE}-{preset}", figure_formats)
        few = (f" Only {len(seeds)} seed(s): the scorecard is meant for five or more."
               if len(seeds) < 5 else "")
        few += _calibration_seed_note(seeds)
        scorecard_lines += [
            f"## Fidelity scorecard — preset `{preset}`", "",
            f"Seeds {', '.join(map(str, seeds))}; use cases {', '.join(map(str, use_cases))}.{few} "
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
    results.write_text_atomic(out / fidelity.FIDELITY_FILE,
                              pd.concat(cards, ignore_index=True).to_csv(index=False))
    results.write_text_atomic(out / feasibility.FEASIBILITY_FILE,
                              pd.concat(checks, ignore_index=True).to_csv(index=False))
    return scorecard_lines, scorecard_tables


def write_report(out: Path, use_cases: Sequence[int], presets: Sequence[str], seeds: Sequence[int],
                 command: str, learning_rate: float | None = None,
                 figure_formats: Sequence[str] = DEFAULT_FIGURE_FORMATS) -> Path:
    """Assemble REPORT.md and its tables, figures and CSVs from the runs under ``out``.

    Args:
        out: the reproduction's folder; each run in ``out/RUN_FOLDER``.
        use_cases: the use cases, in the report's order.
        presets: the presets, in the report's order.
        seeds: the seeds every (use case, preset) ran.
        command: the command line that made the runs (the report cites it).
        learning_rate: the learning rate every run used instead of its preset's, if any.
        figure_formats: the formats of the report's figures (defaults.FIGURE_FORMATS).

    Returns:
        The path of REPORT.md.
    """
    sections: list[str] = []
    section_tables: dict[str, str] = {}
    speedups = []
    methods_rows: list[pd.DataFrame] = []  # the users' own policies' numbers (methods.csv)
    differences: list[str] = []  # how any run's setting departs from the paper's
    summaries: dict[str, dict[int, list[pd.DataFrame]]] = {p: {} for p in presets}
    worlds: dict[str, list[feasibility.WorldRun]] = {p: [] for p in presets}
    for use_case in use_cases:
        for preset in presets:
            folders = [out / RUN_FOLDER.format(use_case=use_case, preset=preset, seed=seed)
                       for seed in seeds]
            lines, tables, theirs = _section(use_case, preset, folders, out, figure_formats)
            sections += lines
            section_tables.update(tables)
            methods_rows.append(theirs)
            summaries[preset][use_case] = [results.read_summary_csv(f) for f in folders]
            for folder in folders:
                differences += [d for d in results.setting_differences(
                    results.read_run_json(folder / results.RUN_FILE)) if d not in differences]
            worlds[preset] += [feasibility.read_world_run(f) for f in folders]
            table = results.aggregate_speedups(folders)
            table.insert(1, "preset", preset)
            speedups.append(table)

    header = _header(command, differences, learning_rate)
    scorecard_lines, scorecard_tables = _scorecards(out, use_cases, presets, seeds, summaries, worlds,
                                                    figure_formats)
    # Tables in the order REPORT.md shows them: scorecards first, then each use case.
    table_paths = latex.write_tables(out, {**scorecard_tables, **section_tables})
    report = "\n".join(header + scorecard_lines + sections
                       + latex.tables_markdown(table_paths, out) + [""])
    results.write_text_atomic(out / REPORT_FILE, report)
    all_speedups = pd.concat(speedups, ignore_index=True)
    results.write_text_atomic(out / SPEEDUPS_FILE, all_speedups.to_csv(index=False))
    theirs = [rows for rows in methods_rows if not rows.empty]
    if theirs:
        results.write_text_atomic(out / METHODS_FILE, pd.concat(theirs, ignore_index=True).to_csv(index=False))
    return out / REPORT_FILE
