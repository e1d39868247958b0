"""summary.md gains a "Failures and energy" section only in a run whose servers fail."""

from __future__ import annotations

import dataclasses

import numpy as np

from tests.results_helpers import make_requests, make_run
from yafs_safetail.results.report import summary_markdown
from yafs_safetail.results.stats import summarize

FAILURES = {"down_file": None, "enabled": True, "mttf_s": 240.0, "mttr_s": 60.0, "timeout_s": 12.5,
            "unavailability": 0.2}


def test_a_run_with_failures_lists_each_methods_success_and_energy():
    summary = summarize(make_requests(np.random.default_rng(3)))
    run = dataclasses.replace(make_run(), extra={"failures": FAILURES})
    text = summary_markdown(summary, run)
    section = text[text.index("## Failures and energy"):]
    assert "each server down 20% of the time, mean repair 60 s" in section
    assert "waits 12.500 s" in section
    rows = [line for line in section.splitlines() if line.startswith("| ") and not line.startswith("| method")]
    assert [row.split(" | ")[0].removeprefix("| ") for row in rows] == list(summary["method"])
    safetail = summary.set_index("method").loc["SafeTail"]
    assert f"| SafeTail | {safetail.success_rate:.3f} |" in section


def test_without_failures_the_report_is_as_before():
    summary = summarize(make_requests(np.random.default_rng(3)))
    plain = summary_markdown(summary, make_run())
    off = dict(FAILURES, enabled=False)
    assert summary_markdown(summary, dataclasses.replace(make_run(), extra={"failures": off})) == plain
    assert "## Failures and energy" not in plain


def test_the_heading_names_the_settings_a_run_changed():
    from pathlib import Path

    from yafs_safetail.runs.provenance import titled_settings
    from yafs_safetail.settings.declare import changed_settings
    from yafs_safetail.settings.experiment import ExperimentConfig

    assert changed_settings(ExperimentConfig(use_case=2, seed=7, steps_scale=0.1, figures=False), skip=titled_settings()) == ()
    changed = changed_settings(ExperimentConfig(failure_probability=0.2, topology=Path("t/mesh.json")),
                               skip=titled_settings())
    assert set(changed) == {"--failure-probability 0.2", "--topology mesh.json"}
    summary = summarize(make_requests(np.random.default_rng(3)))
    run = dataclasses.replace(make_run(), extra={"changed_settings": list(changed)})
    heading = summary_markdown(summary, run).splitlines()[0]
    assert heading.endswith("seed 0; " + ", ".join(changed))
    assert summary_markdown(summary, make_run()).splitlines()[0].endswith("seed 0")


def test_a_changed_setting_reads_the_same_in_any_run_and_any_folder():
    from yafs_safetail.settings.declare import shown_value

    class UsersMethod:
        spec = "Mine=/some/where/policy.py:Cls"

    assert shown_value((UsersMethod(), UsersMethod())) == "Mine=policy.py:Cls,Mine=policy.py:Cls"
    assert shown_value(object()) == "object"  # never a repr with an address
