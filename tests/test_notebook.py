"""examples/quickstart.ipynb runs from top to bottom in a Jupyter kernel, at a tiny budget, and
shows what it promises: the summary table, the paper's Fig. 5 panels, a latency CDF and the
comparison of NearestFree with SafeTail over seeds with intervals.

The budget comes in as papermill does it: a cell added after the one tagged ``parameters``.
"""

from __future__ import annotations

import os
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "examples" / "quickstart.ipynb"
SEEDS = (0, 1)
TINY_PARAMETERS = f"STEPS_SCALE = 0.02\nSEEDS = {list(SEEDS)}\n"
#: Panels (a)-(g), the latency CDF and the p99 bar chart of the comparison.
EXPECTED_IMAGES = 7 + 1 + 1


def _with_parameters(notebook: nbformat.NotebookNode, source: str) -> nbformat.NotebookNode:
    tagged = [i for i, cell in enumerate(notebook.cells) if "parameters" in cell.metadata.get("tags", [])]
    assert len(tagged) == 1, "the notebook needs exactly one cell tagged 'parameters'"
    notebook.cells.insert(tagged[0] + 1, nbformat.v4.new_code_cell(
        source, metadata={"tags": ["injected-parameters"]}))
    return notebook


def _text(output: nbformat.NotebookNode) -> str:
    return str(output.get("text", "")) + str(output.get("data", {}).get("text/plain", ""))


@pytest.fixture(scope="module")
def executed(tmp_path_factory: pytest.TempPathFactory) -> tuple[nbformat.NotebookNode, Path]:
    """The notebook run in a fresh kernel whose working folder is a temporary one."""
    folder = tmp_path_factory.mktemp("notebook")
    notebook = _with_parameters(nbformat.read(NOTEBOOK, as_version=4), TINY_PARAMETERS)
    # The kernel is another process: it must import this checkout's package, whatever the
    # environment's installed copy points at.
    previous = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), previous]))
    try:
        # Raises CellExecutionError, with the cell and its traceback, if any cell fails.
        NotebookClient(notebook, timeout=300, kernel_name="python3",
                       resources={"metadata": {"path": str(folder)}}).execute()
    finally:
        if previous is None:
            del os.environ["PYTHONPATH"]
        else:
            os.environ["PYTHONPATH"] = previous
    return notebook, folder


def test_the_committed_notebook_has_no_outputs():
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    for cell in notebook.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [] and cell.execution_count is None, cell.source[:60]


def test_the_notebook_runs_and_shows_every_result(executed: tuple[nbformat.NotebookNode, Path]):
    notebook, folder = executed
    outputs = [output for cell in notebook.cells if cell.cell_type == "code" for output in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) == EXPECTED_IMAGES
    summary = next(_text(o) for o in outputs if "target_met_rate" in _text(o))
    assert "SafeTail" in summary and "MinProp-1" in summary
    comparison = next(_text(o) for o in outputs if "p99_s_high" in _text(o))
    for method in ("SafeTail", "NearestFree", "Oracle"):
        assert method in comparison
    # The readable table: every method's p99 as "mean [low, high]".
    assert any("NearestFree" in _text(o) and "[" in _text(o) for o in outputs)
    # The runs it made, in its working folder, at the injected budget and seeds.
    runs = sorted(p.name for p in (folder / "results" / "quickstart").iterdir())
    assert runs == ["uc1-nearestfree-s0", "uc1-nearestfree-s1", "uc1-s0"]
    from yafs_safetail import api

    first = api.read_results(folder / "results" / "quickstart" / "uc1-s0")
    assert "steps_scale=0.02" in first.run.command
    assert (first.folder / "figures").is_dir()
    compared = api.read_results(folder / "results" / "quickstart" / "uc1-nearestfree-s1")
    assert "NearestFree" in list(compared.summary["method"]) and compared.run.seed == 1
