"""--help and a bad argument answer before anything heavy loads (issue 30: within 0.3 s).

Each case runs in a fresh interpreter and lists, at exit, which heavy libraries were imported.
The run command's options come from settings.experiment, so this also guards that module's imports.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]
HEAVY = ("numpy", "pandas", "scipy", "simpy", "networkx", "tensorflow", "keras", "matplotlib", "gymnasium")
#: Prints the heavy modules loaded when the interpreter ends, then runs argv[1:] as the command.
PROBE = f"""
import atexit, runpy, sys
atexit.register(lambda: print("loaded:", sorted(m for m in {HEAVY!r} if m in sys.modules), file=sys.stderr))
args = sys.argv[1:]
if args[0] == "yafs-safetail":
    from yafs_safetail.cli import main
    sys.exit(main(args[1:]))
sys.argv = args
runpy.run_path(args[0], run_name="__main__")
"""
RUN_SCRIPT = str(REPOSITORY / "experiments" / "run_usecase.py")
SWEEP_SCRIPT = str(REPOSITORY / "experiments" / "load_sweep.py")
CASES = {
    "run --help": (["yafs-safetail", "run", "--help"], 0),
    "run --uc 7": (["yafs-safetail", "run", "--uc", "7"], 2),
    "script --help": ([RUN_SCRIPT, "--help"], 0),
    "script --uc 7": ([RUN_SCRIPT, "--uc", "7"], 2),
    "script --steps-scale -1": ([RUN_SCRIPT, "--uc", "1", "--steps-scale", "-1"], 2),
    "script --preset bogus": ([RUN_SCRIPT, "--uc", "1", "--preset", "bogus"], 2),
    "listing": (["yafs-safetail", "--help"], 0),
    **{f"{command} --help": (["yafs-safetail", command, "--help"], 0)
       for command in ("reproduce", "campaign", "calibrate", "compare", "figures", "feasibility")},
    "reproduce --uc 9": (["yafs-safetail", "reproduce", "--uc", "9"], 2),
    "figures --figure-format svg": (["yafs-safetail", "figures", "unused", "--figure-format", "svg"], 2),
    "feasibility without a folder": (["yafs-safetail", "feasibility"], 2),
    "learning rate --help": ([str(REPOSITORY / "experiments" / "choose_learning_rate.py"), "--help"], 0),
    "learning rate --uc 7": ([str(REPOSITORY / "experiments" / "choose_learning_rate.py"), "--uc", "7"], 2),
    # The sweeps' options come from runs.sweep_config, so these guard its imports too.
    **{f"{command} --help": (["yafs-safetail", command, "--help"], 0)
       for command in ("sweep", "failure-sweep", "mechanism")},
    **{f"{script} --help": ([str(REPOSITORY / "experiments" / f"{script}.py"), "--help"], 0)
       for script in ("load_sweep", "failure_sweep", "training_mechanism")},
    "sweep --loads 0": (["yafs-safetail", "sweep", "--loads", "0", "--out", "unused"], 2),
    "load_sweep --links bogus": ([SWEEP_SCRIPT, "--links", "bogus", "--out", "unused"], 2),
    "load_sweep --objectives bogus": ([SWEEP_SCRIPT, "--objectives", "bogus", "--out", "unused"], 2),
    "load_sweep --safetail-dispatch bogus": ([SWEEP_SCRIPT, "--safetail-dispatch", "bogus", "--out", "unused"], 2),
    "failure-sweep --failure-levels 2": (["yafs-safetail", "failure-sweep", "--failure-levels", "2",
                                          "--out", "unused"], 2),
    "failure_sweep --failure-mttr-s 0": ([str(REPOSITORY / "experiments" / "failure_sweep.py"), "--failure-mttr-s", "0",
                                  "--out", "unused"], 2),
    "mechanism --loads 0": (["yafs-safetail", "mechanism", "--loads", "0", "--out", "unused"], 2),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_help_and_argument_errors_load_nothing_heavy(case):
    argv, expected_code = CASES[case]
    done = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True,
                          cwd=REPOSITORY, timeout=120)
    assert done.returncode == expected_code, done.stderr[-2000:]
    lines = done.stderr.splitlines()
    assert lines[-1] == "loaded: []", done.stderr[-2000:]
    if expected_code == 0:
        assert done.stdout.startswith("usage:")
    else:  # the one-line error, nothing else
        assert len(lines) == 2 and lines[0].startswith("error: "), done.stderr



VERSION_CASES = {
    "console": ["yafs-safetail", "--version"],
    "run": ["yafs-safetail", "run", "--version"],
    "sweep": ["yafs-safetail", "sweep", "--version"],
    "figures": ["yafs-safetail", "figures", "--version"],
    "script": [RUN_SCRIPT, "--version"],
}


@pytest.mark.parametrize("case", sorted(VERSION_CASES))
def test_version_answers_with_the_package_version_and_loads_nothing_heavy(case):
    from yafs_safetail import __version__

    done = subprocess.run([sys.executable, "-c", PROBE, *VERSION_CASES[case]], capture_output=True,
                          text=True, cwd=REPOSITORY, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout == f"yafs-safetail {__version__}\n"
    assert done.stderr.splitlines() == ["loaded: []"], done.stderr[-2000:]
