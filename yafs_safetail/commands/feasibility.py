"""What any policy could reach in the worlds of some run folders: the ceiling, then the verdict
per use case and percentile.

    yafs-safetail feasibility DIR [DIR ...]

Prints the one-line ceiling and the table REPORT.md's feasibility section shows, read from
Oracle's and the baselines' latencies and the targets alone
(yafs_safetail.results.feasibility). The table is the result: --quiet prints it too, as
compare does without --out.
"""

from __future__ import annotations

from collections.abc import Sequence

from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    run_script,
)


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(
        prog="python -m yafs_safetail.commands.feasibility",
        description="What any policy could reach in the worlds of these run folders (from "
                    "yafs-safetail run or reproduce; one or more use cases, the same seeds "
                    "for each): which of the paper's statements can hold together at each "
                    "percentile, read from Oracle's and the baselines' latencies and the "
                    "targets alone.",
    )
    add_plumbing(parser, "directories", metavar="DIR", nargs="+", help="results folders of runs")
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the folders, with pandas.
    from yafs_safetail.results.feasibility import (
        ceiling_line,
        check_all,
        feasibility_markdown,
        read_world_run,
    )

    worlds = [read_world_run(folder) for folder in args.directories]
    print(ceiling_line(worlds))
    print()
    print(feasibility_markdown(check_all(worlds)), end="")
    return 0


if __name__ == "__main__":
    run_script(main)
