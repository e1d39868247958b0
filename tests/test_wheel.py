"""The command lives in the package: a built wheel, installed in a fresh virtual environment,
runs ``yafs-safetail`` from any folder, with no checkout on the path (issue 29, "Done when").

The default input files (topologies/, placements/, traces/) stay at the checkout's root, where
users edit them; setup.py copies what yafs_safetail/defaults.py's ``DATA_FILES`` lists into the
wheel. The fast test checks that list covers every default file; the slow one builds, installs
and runs the wheel (about two minutes on 2 cores).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from yafs_safetail import defaults

REPOSITORY = Path(__file__).resolve().parents[1]


def _listed_files() -> set[Path]:
    return {path for folder, patterns in defaults.DATA_FILES.items() for pattern in patterns
            for path in (REPOSITORY / folder).glob(pattern) if path.is_file()}


def test_the_wheel_carries_every_default_file():
    # Every file of the default folders but the tools that make them (traces/*.py).
    present = {path for folder in defaults.DATA_FILES for path in (REPOSITORY / folder).rglob("*")
               if path.is_file() and path.suffix not in (".py", ".pyc")}
    listed = _listed_files()
    assert present == listed, sorted(str(p.relative_to(REPOSITORY)) for p in present ^ listed)
    assert {defaults.DEFAULT_TOPOLOGY, defaults.DEFAULT_PLACEMENT} <= listed
    # Every topology has its default placement (placements/<the topology's file name>).
    for topology in (REPOSITORY / "topologies").glob("*.json"):
        assert defaults.default_placement(topology) in listed, topology.name
    # Run from the checkout, the package reads the checkout's own files.
    assert defaults.DATA_ROOT == REPOSITORY and defaults.DEFAULT_TRACE_DIR == REPOSITORY / "traces"


def _copy_of_the_checkout(destination: Path) -> Path:
    """The checkout's files (tracked and new, not ignored) in ``destination``: the build writes
    build/ and *.egg-info beside the sources, which must not land in the checkout."""
    listed = subprocess.run(["git", "-C", str(REPOSITORY), "ls-files", "--cached", "--others",
                             "--exclude-standard", "-z"], capture_output=True, check=False)
    if listed.returncode != 0:
        pytest.skip("git is needed to list the checkout's files")
    for name in filter(None, listed.stdout.decode().split("\0")):
        source = REPOSITORY / name
        if source.is_file():
            (destination / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, destination / name)
    return destination


@pytest.mark.slow
def test_an_installed_wheel_runs_outside_the_checkout(tmp_path):
    source = _copy_of_the_checkout(tmp_path / "source")
    wheels = tmp_path / "wheels"
    # No build isolation: the build uses this interpreter's setuptools (no download needed).
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                    "-w", str(wheels), str(source)], check=True, capture_output=True, timeout=600)
    (wheel,) = wheels.glob("yafs_safetail-*.whl")
    venv = tmp_path / "venv"
    # The system's packages give the dependencies (nothing is downloaded); the venv's own
    # site-packages come first, so its yafs_safetail wins over any other install.
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True, timeout=300)
    python, command = venv / "bin" / "python", venv / "bin" / "yafs-safetail"
    subprocess.run([str(python), "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)],
                   check=True, capture_output=True, timeout=300)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}

    def run(*argv: str | Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run([str(arg) for arg in argv], cwd=elsewhere, env=environment,
                              capture_output=True, text=True, timeout=1200)

    # Every module of the package comes from the wheel: none from the checkout, none from
    # another install of the package (an editable one can lend a subpackage the wheel lacks).
    where = run(python, "-c", "import sys, yafs_safetail.commands.run_usecase, yafs_safetail.runs.experiment; "
                "from yafs_safetail import defaults; print(defaults.DATA_ROOT); "
                "print(*(m.__file__ for n, m in sys.modules.items() if n.startswith('yafs_safetail')))")
    assert where.returncode == 0, where.stderr
    data_root, *module_files = map(Path, where.stdout.split())
    assert data_root.is_relative_to(venv), where.stdout
    assert module_files and all(path.is_relative_to(venv) for path in module_files), where.stdout
    listing = run(command, "--help")
    assert listing.returncode == 0, listing.stderr
    assert all(f"  {name} " in listing.stdout for name in ("run", "reproduce", "campaign", "sweep", "figures"))
    out = elsewhere / "uc1"
    done = run(command, "run", "--uc", "1", "--steps-scale", "0.05", "--out", out)
    assert done.returncode == 0, done.stderr[-3000:]
    written = {path.name for path in out.iterdir()}
    assert {"requests.csv", "summary.csv", "summary.md", "run.json", "figures"} <= written, written
    assert '"topology": "topologies/paper_5servers.json"' in (out / "run.json").read_text()
