"""The lock of library versions (issue 39): it pins what setup.cfg asks for, within its ranges,
and a run made with other versions says so in run.json and summary.md."""

from __future__ import annotations

import configparser
import json
from pathlib import Path

import pytest
from packaging.requirements import Requirement

from yafs_safetail import defaults, versions
from yafs_safetail.results import RunMetadata
from yafs_safetail.results.report import summary_markdown

REPOSITORY = Path(__file__).resolve().parents[1]


def _requirements() -> list[Requirement]:
    setup = configparser.ConfigParser()
    setup.read(REPOSITORY / "setup.cfg")
    lines = setup["options"]["install_requires"].splitlines() + setup["options.extras_require"]["dev"].splitlines()
    return [Requirement(line) for line in (line.split("#")[0].strip() for line in lines) if line]


def test_the_lock_pins_every_requirement_within_setup_cfg_ranges():
    locked = versions.locked_versions()
    assert defaults.LOCK_FILE == REPOSITORY / "constraints.txt"
    for requirement in _requirements():
        name = versions.canonical(requirement.name)
        assert name in locked, f"constraints.txt does not pin {name}; rerun its command (docs/results.md)"
        assert requirement.specifier.contains(locked[name], prereleases=True), (
            f"constraints.txt pins {name}=={locked[name]}, outside setup.cfg's {requirement}")
    assert set(versions.RESULT_PACKAGES) <= set(locked)


def test_differences_name_only_the_packages_off_the_lock():
    locked = {"numpy": "2.4.6", "keras": "3.15.1", "ml-dtypes": "0.6.0"}
    installed = {"numpy": "2.4.6", "keras": "3.12.0", "ML_Dtypes": None, "simpy": "4.1.2"}
    assert versions.differences_from_lock(installed, locked) == {
        "keras": {"installed": "3.12.0", "locked": "3.15.1"},
        "ML_Dtypes": {"installed": None, "locked": "0.6.0"}}


def test_a_missing_lock_pins_nothing(tmp_path):
    assert versions.locked_versions(tmp_path / "none.txt") == {}
    lock = tmp_path / "lock.txt"
    lock.write_text("# a comment\nkeras==3.15.1\n    # via x\nnumpy==2.4.6 ; python_version < '3.12'\n")
    assert versions.locked_versions(lock) == {"keras": "3.15.1", "numpy": "2.4.6"}
    fields = versions.run_json_fields(lock)
    assert set(fields[versions.LIBRARY_VERSIONS_KEY]) == set(versions.RESULT_PACKAGES)


def _run(extra: dict[str, object]) -> RunMetadata:
    return RunMetadata(use_case=1, use_case_name="x", preset="paper", seed=0, n_servers=5, beta=200,
                       train_steps=10, test_steps=10, topology="t.json", methods=["Oracle"],
                       package_version="0", command="c", extra=extra)


def test_summary_md_says_when_the_versions_are_not_the_locks():
    import pandas as pd

    summary = pd.DataFrame({"method": ["Oracle"], "n_requests": [10], "p50_s": [1.0], "p90_s": [1.0],
                            "p95_s": [1.0], "p99_s": [1.0], "mean_access_rate": [1.0],
                            "mean_n_selected": [5.0], "mean_target_s": [1.0], "target_met_rate": [1.0],
                            "fallback_rate": [0.0], "thin_percentiles": [""]})
    differ = {"keras": {"installed": "3.12.0", "locked": "3.15.1"}}
    noted = summary_markdown(summary, _run({versions.NOT_THE_LOCK_KEY: differ}))
    assert "**Not the locked library versions:** keras 3.12.0 (lock 3.15.1)" in noted
    assert "Not the locked" not in summary_markdown(summary, _run({}))


@pytest.mark.parametrize("lock_matches", [True, False])
def test_run_json_records_versions_and_a_note_only_off_the_lock(tmp_path, lock_matches):
    installed = versions.installed_versions()
    lock = tmp_path / "lock.txt"
    numpy_pin = installed["numpy"] if lock_matches else "0.0.1"
    lock.write_text(f"numpy=={numpy_pin}\n")
    fields = json.loads(json.dumps(versions.run_json_fields(lock)))
    assert fields[versions.LIBRARY_VERSIONS_KEY]["numpy"] == installed["numpy"]
    assert (versions.NOT_THE_LOCK_KEY in fields) is not lock_matches


def test_the_cpu_is_recorded_with_the_flags_that_pick_tensorflows_kernels(tmp_path, monkeypatch):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor : 0\nmodel name : Some CPU\nflags : fpu avx2 fma avx512f sse4_2\n"
                       "processor : 1\nmodel name : Some CPU\nflags : fpu\n")
    monkeypatch.setenv("ONEDNN_MAX_CPU_ISA", "AVX2")
    cpu = versions.cpu_fields(cpuinfo)
    assert cpu["model"] == "Some CPU" and cpu["flags"] == ["avx2", "fma", "avx512f"]
    assert cpu["onednn_max_cpu_isa"] == "AVX2"
    assert versions.cpu_fields(tmp_path / "none")["flags"] == []
