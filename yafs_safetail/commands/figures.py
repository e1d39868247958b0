"""Redraw every figure of one run's results folder from its files.

    yafs-safetail figures DIR [--figure-format png,pdf]

Reads DIR/requests.csv and DIR/run.json and writes, into DIR/figures, the paper's Figs. 5-7
(a)-(g), p99_vs_energy and latency_cdf; --quiet prints only DIR/figures. The drawing is
yafs_safetail.results.figures.run_figures.draw_figures.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from yafs_safetail.cli import (
    ArgumentParser,
    add_plumbing,
    add_verbosity_options,
    configure_verbosity,
    print_result,
    run_script,
)
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.options import add_options


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(
        prog="python -m yafs_safetail.commands.figures",
        description="Redraw the paper's Figs. 5-7 (a)-(g), p99_vs_energy and latency_cdf from a results folder "
                    "(requests.csv and run.json) into DIR/figures.",
    )
    add_plumbing(parser, "directory", metavar="DIR", help="results folder of one run")
    add_options(parser, ExperimentConfig, only=("figure_formats",))
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_verbosity(args)
    # The arguments are checked: now the folder, with pandas and matplotlib.
    from yafs_safetail.results.figures.run_figures import FIGURES_DIR, draw_figures

    written = draw_figures(args.directory, formats=args.figure_formats)
    folder = Path(args.directory) / FIGURES_DIR
    print_result(args, folder, f"wrote {len(written)} files to {folder}")
    return 0


if __name__ == "__main__":
    run_script(main)
