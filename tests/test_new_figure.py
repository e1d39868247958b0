"""A new figure of every run is one function: added here (in a fresh interpreter, to
``results.figures.run_figures``) under ``run_figure``, ``yafs-safetail figures`` draws it beside
the others, and every run's figures include it."""

from __future__ import annotations

import shutil
from pathlib import Path

from in_process import run_usecase_here
from source_addition import appended, run_probe

REPOSITORY = Path(__file__).resolve().parents[1]
#: The function, added to the module's source as it is imported: nothing on disk changes.
HOOK = appended("yafs_safetail.results.figures.run_figures", """

@run_figure("servers", "servers_per_request")
def _servers_per_request(inputs):
    figure, axes = _new_figure(inputs.run, "servers per request")
    axes.bar(inputs.summary["method"], inputs.summary["mean_n_selected"])
    return figure
""")
PROBE = """
import json, sys
from yafs_safetail.commands import figures
code = figures.main([sys.argv[1], "--quiet"])
print(json.dumps(code))
"""


def _figures_drawn(folder: Path, add: bool) -> list[str]:
    assert run_probe(HOOK, PROBE, add, str(folder)) in (0, None)  # the command's exit code
    return sorted(path.name for path in (folder / "figures").iterdir())


def test_a_new_figure_is_one_function(tmp_path):
    done = run_usecase_here("--uc", "1", "--seed", "2", "--steps-scale", "0.02", "--no-figures",
                            "--out", tmp_path / "run")
    assert done.returncode == 0, done.stderr
    shutil.copytree(tmp_path / "run", tmp_path / "plain")
    plain = _figures_drawn(tmp_path / "plain", add=False)
    added = _figures_drawn(tmp_path / "run", add=True)
    assert "servers_per_request.png" not in plain and len(plain) == 9
    assert added == sorted([*plain, "servers_per_request.png"])
