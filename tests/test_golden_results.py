"""The golden check: small runs of every kind write the same results files as when the golden
was recorded (issue 29: a restructure must leave every results file byte-identical).

Each scenario runs an entry point on a small budget and hashes its results files. What
legitimately differs between two checkouts or two folders is taken out before hashing: the
run's own command line and output path, the checkout's absolute path, campaign run ids (they
hash the code version, which every commit changes), and the library versions and processor that
run.json records (``library_versions``, ``cpu``). ``run.log``, campaign logs and figures are not
compared (times, library versions). A saved policy (``.keras``) is compared by what it holds, its configuration
and every weight bit for bit, not by the bytes of its zip, whose ``metadata.json`` names the
Keras version that wrote it.

The golden files were recorded with the lock's library versions (``constraints.txt``, installed
by the README's set-up command and ``.ci/run``): another TensorFlow or Keras may train another
network, and then SafeTail's files differ while every baseline's row stays (docs/results.md,
"Versions"); a run made without the lock says so in its run.json and summary.md. When a change
is *meant* to change results, rerun with ``YAFS_SAFETAIL_UPDATE_GOLDEN=1`` to rewrite
``tests/golden/results.json`` and say why in the commit.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest

from yafs_safetail import versions

REPOSITORY = Path(__file__).resolve().parents[1]
GOLDEN_FILE = REPOSITORY / "tests" / "golden" / "results.json"
UPDATE = os.environ.get("YAFS_SAFETAIL_UPDATE_GOLDEN") == "1"
#: Keys of a JSON results file that name where or when it was made, not what it found.
VOLATILE_KEYS = frozenset({"command", "load_runs", "campaign_run_id", "code_version", "created",
                           "finished", "wall_s", "library_versions", "cpu", "numerics"})
#: Files never compared: times and library versions.
SKIPPED_NAMES = frozenset({"run.log", "campaign.log", "campaign.json", ".campaign.lock"})
SKIPPED_SUFFIXES = frozenset({".png", ".pdf"})
RUN_ID_SUFFIX = re.compile(r"-[0-9a-f]{12}$")

SCENARIOS: dict[str, list[str]] = {
    # UC2's budget is the smallest at which SafeTail still trains (κ = 128 of 50·β = 6000 steps).
    **{f"uc{uc}": ["experiments/run_usecase.py", "--uc", str(uc), "--seed", "0",
                   "--steps-scale", "0.03", "--no-figures", "--quiet"] for uc in (1, 2, 3)},
    "sweep": ["experiments/load_sweep.py", "--users", "10", "--loads", "0.3,0.8",
              "--steps-scale", "0.02", "--methods", "Oracle,MinLoad-1,Tied", "--seed", "3",
              "--quiet"],
}
CAMPAIGN_GRID = """
[base]
use_case = 1
steps_scale = 0.02
figures = false

[axes]
preset = ["tuned", "paper-literal"]
"""


def _policy_content(path: Path) -> bytes:
    """What a saved policy holds: its configuration (keys sorted) and, for every weight array
    in file order, its name, dtype, shape and bytes. Not the zip's ``metadata.json`` (the Keras
    version and save date) nor the HDF5 file's layout."""
    with zipfile.ZipFile(path) as archive:
        parts = [json.dumps(json.loads(archive.read("config.json")), sort_keys=True).encode()]
        weights = io.BytesIO(archive.read("model.weights.h5"))
    with h5py.File(weights, "r") as store:
        arrays: list[tuple[str, h5py.Dataset]] = []
        store.visititems(lambda name, item: arrays.append((name, item))
                         if isinstance(item, h5py.Dataset) else None)
        for name, array in arrays:
            values = array[()]
            parts.append(f"{name} {values.dtype.str} {values.shape}".encode())
            parts.append(values.tobytes())
    return b"\0".join(parts)


def _normalised(path: Path, out: Path) -> bytes:
    """The bytes of a results file with its place of making taken out."""
    if path.suffix == ".keras":
        return _policy_content(path)
    data = path.read_bytes()
    if path.suffix in (".json", ".md", ".csv", ".tex"):
        text = data.decode("utf-8").replace(str(out), "<OUT>").replace(str(REPOSITORY), "<REPO>")
        if path.suffix == ".json" and path.name != "policy.keras.json":
            text = json.dumps(_drop_volatile(json.loads(text)), sort_keys=True)
        data = text.encode("utf-8")
    return data


def _drop_volatile(value: object) -> object:
    if isinstance(value, dict):
        return {k: _drop_volatile(v) for k, v in value.items() if k not in VOLATILE_KEYS}
    if isinstance(value, list):
        return [_drop_volatile(v) for v in value]
    return value


def _stable_name(relative: Path) -> str:
    """A results file's path without campaign run ids (``seed0-paper-0f7ed8b61e4c`` ->
    ``seed0-paper``): a run id hashes the code version, which every commit changes."""
    parts = [RUN_ID_SUFFIX.sub("", part) for part in relative.parts]
    return "/".join(parts)


def digests(out: Path) -> dict[str, str]:
    """sha256 of every compared results file under ``out``, by relative path."""
    found = {}
    for path in sorted(out.rglob("*")):
        if not path.is_file() or path.name in SKIPPED_NAMES or path.suffix in SKIPPED_SUFFIXES:
            continue
        found[_stable_name(path.relative_to(out))] = hashlib.sha256(_normalised(path, out)).hexdigest()
    return found


def _run(argv: list[str], out: Path) -> None:
    done = subprocess.run([sys.executable, *argv, "--out", str(out)], capture_output=True,
                          text=True, cwd=REPOSITORY, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]


def _check(name: str, found: dict[str, str]) -> None:
    golden = json.loads(GOLDEN_FILE.read_text()) if GOLDEN_FILE.is_file() else {}
    if UPDATE:
        golden[name] = found
        GOLDEN_FILE.parent.mkdir(parents=True, exist_ok=True)
        GOLDEN_FILE.write_text(json.dumps(golden, indent=1, sort_keys=True) + "\n")
        return
    assert name in golden, f"{GOLDEN_FILE}: no golden for {name!r}; record it (module docstring)"
    expected = golden[name]
    changed = sorted(k for k in expected.keys() | found.keys() if expected.get(k) != found.get(k))
    differ = versions.differences_from_lock(versions.installed_versions(), versions.locked_versions())
    not_locked = ("; not the lock's library versions, with which the golden was recorded: "
                  + ", ".join(f"{k} {v['installed']} (lock {v['locked']})" for k, v in sorted(differ.items()))
                  if differ else "")
    assert not changed, (f"{name}: results files differ from the golden ({GOLDEN_FILE.name}): "
                         f"{', '.join(changed)}{not_locked}")


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_results_files_match_the_golden(name, tmp_path):
    out = tmp_path / "out"
    _run(SCENARIOS[name], out)
    found = digests(out)
    assert any(key.endswith(".csv") for key in found)  # something was compared
    _check(name, found)


def test_campaign_results_match_the_golden(tmp_path):
    grid = tmp_path / "grid.toml"
    grid.write_text(CAMPAIGN_GRID)
    out = tmp_path / "campaign"
    _run(["experiments/campaign.py", "--grid", str(grid), "--workers", "2", "--quiet"], out)
    found = digests(out)
    assert sum(key.endswith("requests.csv") for key in found) == 2
    _check("campaign", found)


def test_the_normaliser_keeps_results_and_drops_only_the_place_of_making(tmp_path):
    out = tmp_path / "x"
    out.mkdir()
    (out / "run.json").write_text(json.dumps({"command": f"run --out {out}", "seed": 1,
                                              "topology": f"{REPOSITORY}/t.json"}))
    (out / "requests.csv").write_text("a,b\n1,2\n")
    first = digests(out)
    (out / "run.json").write_text(json.dumps({"command": "another", "seed": 1,
                                              "topology": f"{REPOSITORY}/t.json"}))
    assert digests(out) == first  # the command is not a result
    (out / "run.json").write_text(json.dumps({"command": "another", "seed": 2,
                                              "topology": f"{REPOSITORY}/t.json"}))
    assert digests(out)["run.json"] != first["run.json"]  # the seed is
    (out / "requests.csv").write_text("a,b\n1,3\n")
    assert digests(out)["requests.csv"] != first["requests.csv"]
    (out / "run.log").write_text("12:00 took 3 s")
    assert "run.log" not in digests(out)
    (out / "seed0-paper-0f7ed8b61e4c").mkdir()
    (out / "seed0-paper-0f7ed8b61e4c" / "summary.csv").write_text("m\n")
    assert "seed0-paper/summary.csv" in digests(out)  # the run id is not a result


def _policy_zip(path: Path, keras_version: str, weight: float) -> None:
    """A file shaped as Keras saves a policy: metadata, configuration and HDF5 weights."""
    weights = io.BytesIO()
    with h5py.File(weights, "w") as store:
        store.create_dataset("layers/dense/vars/0", data=[[weight, 2.0]], dtype="float32")
        store.create_dataset("layers/dense/vars/1", data=[0.5], dtype="float32")
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("metadata.json", json.dumps({"keras_version": keras_version}))
        archive.writestr("config.json", json.dumps({"name": "net", "units": 2}))
        archive.writestr("model.weights.h5", weights.getvalue())


def test_a_policy_is_compared_by_its_weights_not_by_the_keras_version(tmp_path):
    out = tmp_path / "x"
    out.mkdir()
    _policy_zip(out / "policy.keras", "3.15.1", 1.0)
    first = digests(out)["policy.keras"]
    _policy_zip(out / "policy.keras", "3.12.0", 1.0)
    assert digests(out)["policy.keras"] == first  # another Keras wrote the same network
    # One weight's last bit: float32 1.0 -> the next float32 up.
    _policy_zip(out / "policy.keras", "3.15.1", float(np.nextafter(np.float32(1.0), np.float32(2.0))))
    assert digests(out)["policy.keras"] != first
