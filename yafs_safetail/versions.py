"""Which library versions a run used, and whether they are the lock's (``constraints.txt``).

The same seed gives byte-identical results files only with the same libraries: another
TensorFlow or Keras build trains another network (NumPy, SciPy and pandas could move a
baseline's numbers too). ``constraints.txt`` pins the versions the published numbers and the
golden files were made with (docs/results.md, "Versions"); the project still installs and runs
with the wider ranges of ``setup.cfg``, and a run made with other versions says so in
``run.json`` and ``summary.md``.

Standard library only: the sweeps and the light command paths may import it.
"""

from __future__ import annotations

import os
import platform
import re
from importlib import metadata
from pathlib import Path

from yafs_safetail.defaults import LOCK_FILE
from yafs_safetail.numerics import NUMERICS_KEY, numerical_path

#: The distributions whose versions can change a results file: the simulation and the baselines
#: (NumPy, SciPy, pandas, simpy, networkx) and SafeTail's network (TensorFlow, Keras, and
#: ml-dtypes, through which TensorFlow converts its floats). Figures' libraries are left out:
#: figures are not results files.
RESULT_PACKAGES: tuple[str, ...] = ("numpy", "scipy", "pandas", "simpy", "networkx",
                                    "tensorflow-cpu", "keras", "ml-dtypes")
#: ``run.json`` key: the installed version of every package of :data:`RESULT_PACKAGES`.
LIBRARY_VERSIONS_KEY = "library_versions"
#: ``run.json`` key, only when some of those differ from the lock: name -> {installed, locked}.
NOT_THE_LOCK_KEY = "library_versions_not_the_lock"
#: ``run.json`` key: the processor. TensorFlow's CPU kernels pick their code by the instruction
#: set at run time; ``numerics`` pins one path for every x86-64 (recorded as ``numerics``), so
#: the processor is recorded to show which one made a run, not because the files depend on it.
CPU_KEY = "cpu"
#: The instruction-set extensions whose presence changes which kernels TensorFlow (oneDNN) runs.
CPU_FLAGS = ("avx2", "fma", "avx512f", "avx512_vnni", "avx512_bf16", "avx_vnni", "amx_tile")

_PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;#]+)")


def canonical(name: str) -> str:
    """A distribution's name as PEP 503 compares it (``ML_Dtypes`` -> ``ml-dtypes``)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def locked_versions(lock_file: Path = LOCK_FILE) -> dict[str, str]:
    """Every ``name==version`` line of the lock, by canonical name; empty without a lock."""
    if not lock_file.is_file():
        return {}
    pins = {}
    for line in lock_file.read_text(encoding="utf-8").splitlines():
        match = _PIN.match(line.strip())
        if match:
            pins[canonical(match.group(1))] = match.group(2)
    return pins


def installed_versions(names: tuple[str, ...] = RESULT_PACKAGES) -> dict[str, str | None]:
    """The installed version of each distribution (None where it is not installed)."""
    found: dict[str, str | None] = {}
    for name in names:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found


def differences_from_lock(installed: dict[str, str | None],
                          locked: dict[str, str]) -> dict[str, dict[str, str | None]]:
    """The packages whose installed version is not the lock's: name -> installed and locked."""
    return {name: {"installed": version, "locked": locked[canonical(name)]}
            for name, version in installed.items()
            if canonical(name) in locked and version != locked[canonical(name)]}


def cpu_fields(cpuinfo: Path = Path("/proc/cpuinfo")) -> dict[str, object]:
    """The processor: its architecture, model name and instruction-set extensions of
    :data:`CPU_FLAGS` (Linux; elsewhere the architecture alone), and a oneDNN cap if set."""
    model: str | None = None
    flags: set[str] = set()
    if cpuinfo.is_file():
        for line in cpuinfo.read_text(encoding="utf-8", errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and model is None:
                model = value.strip()
            elif key.strip() == "flags" and not flags:
                flags = set(value.split())
    return {"machine": platform.machine(), "model": model,
            "flags": [flag for flag in CPU_FLAGS if flag in flags],
            "onednn_max_cpu_isa": os.environ.get("ONEDNN_MAX_CPU_ISA")}


def run_json_fields(lock_file: Path = LOCK_FILE) -> dict[str, object]:
    """What ``run.json`` records of the libraries and the processor: the versions, those not
    the lock's, the CPU and the network's numerical path."""
    installed = installed_versions()
    differ = differences_from_lock(installed, locked_versions(lock_file))
    return {LIBRARY_VERSIONS_KEY: installed, **({NOT_THE_LOCK_KEY: differ} if differ else {}),
            CPU_KEY: cpu_fields(), NUMERICS_KEY: numerical_path()}


def not_the_lock_note(differ: dict[str, dict[str, str | None]]) -> str:
    """One markdown paragraph for a report made with other versions than the lock's."""
    listed = ", ".join(f"{name} {versions['installed'] or 'not installed'} (lock "
                       f"{versions['locked']})" for name, versions in sorted(differ.items()))
    return (f"**Not the locked library versions:** {listed}. The published numbers and the "
            "golden files were made with `constraints.txt`'s; other versions may train another "
            "network and move SafeTail's rows (docs/results.md, \"Versions\").")
