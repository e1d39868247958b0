"""yafs_safetail.api: a run from Python is the command's run, its results read back, plotted and
compared over seeds; bad input is one line and writes nothing; docs/python_api.md's snippet runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from in_process import run_usecase_here

from yafs_safetail import api
from yafs_safetail.methods import Policy
from yafs_safetail.results import ResultsFileError

ROOT = Path(__file__).resolve().parents[1]
NEAREST_FREE = f"{ROOT / 'examples' / 'custom_policy' / 'nearest_free.py'}:NearestFree"
TINY = {"steps_scale": 0.02, "redundancy_levels": (1, 2)}
SEEDS = (0, 1)


class FirstServer(Policy):
    """Always server 0: a policy defined in a module, passed to run() as a class."""

    def choose(self, observation):
        return [0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    """Two seeds of a tiny UC1 run with the example policy, no figures."""
    base = tmp_path_factory.mktemp("api")
    return {seed: api.run(1, seed=seed, out_dir=base / f"s{seed}", methods=[NEAREST_FREE],
                          figures=False, workers=1 + seed, **TINY)
            for seed in SEEDS}


def test_import_loads_nothing_heavy():
    code = ("import sys; from yafs_safetail import api; "
            "print(sorted(m for m in ('numpy', 'pandas', 'matplotlib', 'tensorflow') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"


def test_a_run_from_python_writes_the_commands_results(runs: dict[int, Path], tmp_path: Path):
    done = run_usecase_here("--uc", "1", "--seed", "0", "--steps-scale", "0.02", "--redundancy", "1,2",
                            "--method", NEAREST_FREE, "--no-figures", "--quiet", "--out", tmp_path / "cli")
    assert done.returncode == 0, done.stderr
    for name in ("requests.csv", "summary.csv"):
        assert (runs[0] / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name


def test_read_results_gives_the_tables_and_run_json(runs: dict[int, Path]):
    results = api.read_results(runs[1])
    assert results.folder == runs[1]
    assert list(results.summary["method"]) == ["SafeTail", "Oracle", "Rand-1", "Rand-2", "MinLoad-1",
                                               "MinLoad-2", "MinProp-1", "MinProp-2", "NearestFree"]
    assert results.run.seed == 1 and results.run.use_case == 1
    test = results.test_requests
    assert set(test["phase"]) == {"test"}
    assert len(test) == results.run.test_steps * len(results.summary)
    assert results.run.command.startswith("yafs_safetail.api.run(1, ")
    assert "steps_scale=0.02" in results.run.command


def test_latency_cdf_draws_each_methods_latencies(runs: dict[int, Path]):
    results = api.read_results(runs[0])
    methods = ["Oracle", "NearestFree"]
    figure = api.latency_cdf(runs[0], methods=methods)
    curves = [line for line in figure.axes[0].get_lines() if line.get_label() in methods]
    assert [line.get_label() for line in curves] == methods
    for line in curves:
        expected_s = np.sort(results.test_requests.loc[
            results.test_requests["method"] == line.get_label(), "latency_s"].to_numpy())
        np.testing.assert_array_equal(line.get_xdata(), expected_s)
        assert line.get_ydata()[-1] == 1.0 and np.all(np.diff(line.get_ydata()) > 0)


def test_paper_figures_gives_the_panels_asked(runs: dict[int, Path]):
    figures = api.paper_figures(api.read_results(runs[0]), panels="ae")
    assert list(figures) == ["a", "e"]
    assert figures["a"].axes[0].get_title().startswith("(a)")
    assert figures["e"].axes[0].get_title().startswith("(e)")


def test_compare_over_seeds_gives_means_and_intervals(runs: dict[int, Path]):
    table = api.compare_over_seeds(list(runs.values()), methods=["NearestFree", "SafeTail"],
                                   metrics=("p99_s",))
    assert list(table["method"]) == ["NearestFree", "SafeTail"]
    assert list(table.columns) == ["method", "p99_s", "p99_s_low", "p99_s_high", "n_seeds"]
    for _, row in table.iterrows():
        per_seed = [float(api.read_results(folder).summary.set_index("method").at[row["method"], "p99_s"])
                    for folder in runs.values()]
        assert row["p99_s"] == pytest.approx(np.mean(per_seed))
        assert min(per_seed) <= row["p99_s_low"] <= row["p99_s"] <= row["p99_s_high"] <= max(per_seed)
        assert row["n_seeds"] == len(SEEDS)


def test_a_policy_class_becomes_the_runs_method():
    from yafs_safetail.api import _user_method

    method = _user_method(FirstServer)
    assert method.spec == f"{__name__}:FirstServer" and method.name == "FirstServer"
    policy = method.make(5, np.random.default_rng(0))
    assert isinstance(policy, FirstServer)


@pytest.mark.parametrize(("call", "message"), [
    (lambda out: api.run(1, out_dir=out, sead=3), r"^run\(\): 'sead' is not a setting; the settings are "),
    (lambda out: api.run(1, out_dir=out, steps_scale=-1), r"^steps_scale: expected .*-1$"),
    (lambda out: api.run(1, out_dir=out, methods=[_local_policy()]),
     r"^run\(\): methods: .*Local is not reachable as .*; define it at the top level"),
    (lambda out: api.run(1, out_dir=out, methods=[42]), r"^run\(\): methods: 42 is neither"),
    (lambda out: api.run(1, out_dir=out, redundancy_levels=2), r"^redundancy_levels: expected "),
    (lambda out: api.run(1, out_dir=out, topology=ROOT / "examples" / "yafs_basic" / "topology.json"),
     r"^run\(\): placement: .*topology.json not found, the default for topology .*; pass placement=$"),
    (lambda out: api.read_results(out), r"results folder not found$"),
    (lambda out: api.paper_figures(out, panels="az"), r"^paper_figures\(\): panels 'az'"),
], ids=["unknown setting", "bad value", "unreachable class", "not a policy", "bad levels", "no placement",
        "no folder", "bad panel"])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path: Path, call, message):
    out = tmp_path / "out"
    with pytest.raises(ValueError) as raised:
        call(out)
    assert re.search(message, str(raised.value)), str(raised.value)
    assert "\n" not in str(raised.value)
    assert list(tmp_path.iterdir()) == []


def _local_policy() -> type[Policy]:
    class Local(Policy):
        def choose(self, observation):
            return [0]

    return Local


def test_bad_method_or_file_names_it(runs: dict[int, Path], tmp_path: Path):
    with pytest.raises(ValueError, match=r"^latency_cdf\(\): methods: 'Nope' has no test rows"):
        api.latency_cdf(runs[0], methods=["Nope"])
    with pytest.raises(ValueError, match=r"^compare_over_seeds\(\): methods: 'Nope' is in none"):
        api.compare_over_seeds(list(runs.values()), methods=["Nope"])
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ResultsFileError, match="summary.csv"):
        api.read_results(empty)


def test_the_documented_snippet_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    text = (ROOT / "docs" / "python_api.md").read_text()
    snippet = re.search(r"```python\n(.*?)```", text, re.S)
    assert snippet is not None
    monkeypatch.chdir(tmp_path)
    exec(compile(snippet.group(1), "docs/python_api.md", "exec"), {})
    assert (tmp_path / "fig_a.png").stat().st_size > 0 and (tmp_path / "cdf.png").stat().st_size > 0
    results = api.read_results(tmp_path / "results" / "uc1-paper-s0-x0.02")
    assert (results.folder / "figures").is_dir()  # figures on by default, as on the command line
