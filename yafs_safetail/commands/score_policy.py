"""Score your policy everywhere: the paper's use cases, many users, failures and a walking user.

    yafs-safetail score --method my_policy.py:MyPolicy --out results/score
    yafs-safetail score --method my.py:Mine --profile full --out results/score-full
    yafs-safetail score --method my.py:Mine --scenarios uc1,load-high --seeds 0,1 --out results/mine

Runs the policy beside SafeTail, Oracle, the fixed baselines and the strongest simple policy
(LeastLoaded-2: each request to the two least-loaded servers of all) in eight scenarios: the
paper's world in use cases 1, 2 and 3 (uc1-uc3); many users sharing the servers at an offered
load of 0.1, 0.5 and 0.9 (load-low, load-mid, load-high; two SafeTails there: the paper's and
the contention-aware SafeTail-CA); servers down 20% of the time (failures); and use case 1 with
the user walking on the campus (walking). Every method meets the same requests in a scenario.

Writes OUT/REPORT.md (the answer first: in how many scenarios your p99 is below or above
SafeTail's; then, per scenario, your median, p99, servers and energy per request beside each
other method's, and your p50 and p99 over theirs with 95% intervals paired by request), OUT/score.csv
(the same rows), OUT/score.png (your p99 over each method's, per scenario) and OUT/score.json
(the suite's settings). Each scenario's runs are in OUT/<scenario>/seed<S>/, each what the run
command or one point of a sweep writes.

--profile quick (default) trains on a quarter of the paper's budget (a tenth with many users),
one seed, 20 users, 5,000 test requests with many users: minutes on two cores, a first look. --profile full: the paper's
budgets, seeds 0,1,2, 50 users: the figures to report (far longer: a cluster's or a night's
work on two cores). The runs form one campaign: the same command on the same --out resumes
after a kill and recomputes no finished run; runs go on every core (--workers N for fewer;
--engine ray for a cluster); the files are the same for any number.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

# Light modules only until the arguments are checked (--help answers at once).
from yafs_safetail import __version__
from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    invocation,
    print_result,
)
from yafs_safetail.runs.engine_options import add_engine_options, engine_keywords
from yafs_safetail.runs.score_suite import SCENARIOS, ScoreSuite
from yafs_safetail.settings.declare import field_of, setting_of
from yafs_safetail.settings.experiment import ExperimentConfig, Task
from yafs_safetail.settings.options import add_list_options, add_options

#: What the suite writes beside its run folders (a folder holding REPORT.md without score.json
#: is not a suite's, and is left alone).
SETTINGS_FILE = "score.json"
KIND = "score_policy"


def _parser() -> ArgumentParser:
    parser = ArgumentParser(prog="score_policy.py", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    add_options(parser, ExperimentConfig, only=("methods",),
                methods={"help": "your Policy, [NAME=]FILE.py:CLASS or module:Class (required, once)"})
    add_options(parser, ScoreSuite, only=("profile",))
    names = tuple(scenario.name for scenario in SCENARIOS)
    add_list_options(parser, ScoreSuite, {"scenario": "--scenarios"},
                     scenario={"default": names, "help": f"a part of the suite (default: all of {','.join(names)})"})
    add_list_options(parser, ExperimentConfig, {"seed": "--seeds"},
                     seed={"default": None, "help": "distinct seeds instead of the profile's"})
    add_plumbing(parser, "--out", type=Path, required=True, help="output folder (new, or this command's to resume)")
    add_plumbing(parser, "--overwrite", action="store_true",
                 help="replace run folders in --out that hold another configuration")
    add_engine_options(parser)
    add_verbosity_options(parser)
    return parser


def _refuse_foreign(out: Path) -> None:
    """A folder with a REPORT.md that this command did not write is not ours to write into."""
    if (out / "REPORT.md").is_file() and not (out / SETTINGS_FILE).is_file():
        raise ValueError(f"--out {out}: holds a REPORT.md that is not a scoring suite's; choose another folder")


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    configure_verbosity(args)
    if len(args.methods) != 1:
        parser.error(f"--method: expected your one policy, got {len(args.methods)}")
    (spec,) = args.methods
    load = setting_of(field_of(Task, "methods")).from_cli
    assert load is not None
    (method,) = load([spec])  # the policy's file and class, loaded and checked: one line if not
    # The arguments are checked: now the campaign and its report, with NumPy and pandas.
    from dataclasses import replace

    from yafs_safetail.results.figures.score import draw_score_figure
    from yafs_safetail.results.files import write_text_atomic
    from yafs_safetail.results.score_report import report_markdown, scenario_requests, score_table
    from yafs_safetail.runs.campaign import engine_free_command, run_campaign
    from yafs_safetail.runs.experiment import check_user_policies
    from yafs_safetail.runs.grid import make_config
    from yafs_safetail.runs.output import refuse_protected
    from yafs_safetail.runs.score_suite import (
        LEAST_LOADED_NAME,
        PAPER_WORLD,
        PROFILES,
        profile_settings,
        run_folder,
        suite_specs,
    )

    command = engine_free_command(invocation("experiments/score_policy.py"), sys.argv[1:] if argv is None else argv)
    out = Path(args.out)
    refuse_protected(out)
    _refuse_foreign(out)
    profile = PROFILES[args.profile]
    if args.seeds is not None:
        profile = replace(profile, seeds=tuple(args.seeds))
    scenarios = tuple(scenario for scenario in SCENARIOS if scenario.name in args.scenarios)
    specs = suite_specs(spec, profile, scenarios)
    paper_world = next((run for run in specs if run.kind == "experiment"), None)
    if paper_world is not None:  # the policy asked for its first request before anything runs
        check_user_policies(make_config(paper_world, out / paper_world.name))
    outcome = run_campaign(specs, out, command=command, **engine_keywords(args))
    if outcome.failed:
        print(f"error: {outcome.failed} run(s) failed (see above); no report written; rerun the "
              "same command to retry them (finished runs are kept)", file=sys.stderr)
        return 1
    requests = {scenario.name: [scenario_requests(out / run_folder(scenario, seed), scenario.world == PAPER_WORLD)
                                for seed in profile.seeds] for scenario in scenarios}
    table = score_table(requests, method.name, LEAST_LOADED_NAME)
    settings = {**profile_settings(profile), "scenarios": [scenario.name for scenario in scenarios],
                "method": spec}
    write_text_atomic(out / "score.csv", table.to_csv(index=False, float_format="%.6g"))
    title = f"{method.name}: p99 over each method's ({profile.name} profile)"
    figures = draw_score_figure(table, out, title, ("png",))
    write_text_atomic(out / SETTINGS_FILE, json.dumps({
        "package_version": __version__, "kind": KIND, "command": command, **settings}, indent=1) + "\n")
    titles = {scenario.name: scenario.title for scenario in scenarios}
    report = report_markdown(table, method.name, titles, settings, command, figures[0].name if figures else None)
    write_text_atomic(out / "REPORT.md", report)
    print_result(args, out, report.split("## Per scenario")[0].rstrip() + f"\n\nreport: {out / 'REPORT.md'}")
    return 0
