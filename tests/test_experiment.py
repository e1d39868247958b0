"""run_experiment in-process on tiny budgets: determinism, seeds, common random numbers, topologies.

The full budget is 50·β training and 20·β test steps; ``steps_scale=0.02`` gives 200 training
and 80 test steps per method for UC1, enough to exercise every phase in about a second.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from yafs_safetail import results
from yafs_safetail.runs.experiment import (
    REPOSITORY,
    YAFS_DIR,
    ExperimentConfig,
    ExperimentError,
    baseline_names,
    run_experiment,
)

TINY = 0.02


def tiny_config(out_dir: Path, **overrides) -> ExperimentConfig:
    settings = dict(use_case=1, seed=5, out_dir=out_dir, steps_scale=TINY, figures=False,
                    write_yafs_csv=True, progress=False, command="test")
    settings.update(overrides)
    return ExperimentConfig(**settings)


def compared_files(folder: Path) -> dict[str, bytes]:
    """Every results file that must be reproducible, by path relative to ``folder``."""
    files = [folder / "requests.csv", folder / "summary.csv", folder / "summary.md",
             folder / "run.json", folder / "policy.keras", folder / "policy.keras.json",
             *sorted((folder / YAFS_DIR).glob("*.csv"))]
    return {str(path.relative_to(folder)): path.read_bytes() for path in files}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two runs with the same config and seed (baselines in a worker process, then all in one
    process), one with another seed (UC1, paper preset)."""
    root = tmp_path_factory.mktemp("experiment")
    first = run_experiment(tiny_config(root / "a", workers=2))
    again = run_experiment(tiny_config(root / "b", workers=1))
    other = run_experiment(tiny_config(root / "c", seed=6))
    return first, again, other


@pytest.fixture(scope="module")
def requests(runs):
    return results.read_requests_csv(runs[0].out_dir / "requests.csv")


def test_same_config_and_seed_give_byte_identical_files_with_any_workers(runs):
    first, again, _ = runs
    a, b = compared_files(first.out_dir), compared_files(again.out_dir)
    # SafeTail train and test, Oracle, nine baselines; each a module and a link CSV.
    assert len([name for name in a if name.startswith(YAFS_DIR)]) == 2 * (2 + 1 + 9)
    assert a.keys() == b.keys()
    for name in a:
        assert a[name] == b[name], f"{name} differs between two runs with the same seed"


def test_a_different_seed_gives_different_results(runs):
    first, _, other = runs
    assert (first.out_dir / "requests.csv").read_bytes() != (other.out_dir / "requests.csv").read_bytes()
    a = pd.read_csv(first.out_dir / "summary.csv").set_index("method")
    b = pd.read_csv(other.out_dir / "summary.csv").set_index("method")
    assert not np.allclose(a.loc["Oracle", "p50_s"], b.loc["Oracle", "p50_s"])


def test_budget_phases_and_methods(runs, requests):
    report = runs[0]
    methods = [results.SAFETAIL, *baseline_names((1, 2, 3))]
    assert list(report.summary["method"]) == methods
    train = requests[requests["phase"] == "train"]
    test = requests[requests["phase"] == "test"]
    assert set(train["method"]) == {results.SAFETAIL}
    assert len(train) == round(50 * 200 * TINY)
    assert (test.groupby("method").size() == round(20 * 200 * TINY)).all()
    assert set(test["method"]) == set(methods)
    for part in ("setup", "tf_import", "simulation", "decisions", "training", "writing", "total"):
        assert report.timings_s[part] >= 0.0


def test_every_method_sees_the_same_requests_per_step(requests):
    test = requests[requests["phase"] == "test"]
    reference = test[test["method"] == results.SAFETAIL].set_index("step")
    for method, rows in test.groupby("method"):
        rows = rows.set_index("step")
        assert list(rows.index) == list(reference.index), method
        assert (rows["request_id"] == reference["request_id"]).all(), method
        assert (rows["target_s"] == reference["target_s"]).all(), method


def test_oracle_is_a_per_request_lower_bound(requests):
    test = requests[requests["phase"] == "test"]
    oracle = test[test["method"] == results.ORACLE].set_index("step")["latency_s"]
    assert (test[test["method"] == results.ORACLE]["n_selected"] == 5).all()
    for method, rows in test.groupby("method"):
        indexed = rows.set_index("step")
        latency = indexed["latency_s"]
        joined = pd.concat({"method": latency, "oracle": oracle}, axis=1, join="inner")
        assert len(joined) == len(oracle), method
        # Where every chosen server refused, the on-device version answers; in the calibrated
        # world it can beat Oracle's slowest admitted copies (yafs_safetail.edge.calibration).
        joined = joined[indexed["fallback"].reindex(joined.index) == 0]
        worse = joined[joined["oracle"] > joined["method"]]
        assert worse.empty, f"Oracle slower than {method} at steps {list(worse.index[:5])}"


def test_baselines_pick_the_subsets_they_promise(runs, requests):
    # The paper preset's world reads the baselines as the original code chose (D16): MinProp-x
    # is the x nearest of three servers drawn per request, not one fixed subset.
    assert results.read_run_json(runs[0].out_dir).baseline_reading == "original-code"
    test = requests[requests["phase"] == "test"]
    for x in (1, 2, 3):
        for family in ("Rand", "MinLoad", "MinProp"):
            rows = test[test["method"] == f"{family}-{x}"]
            assert (rows["n_selected"] == x).all()
        minprop = test[test["method"] == f"MinProp-{x}"]["servers"]
        assert minprop.nunique() > 1
    assert test[test["method"] == "Rand-2"]["servers"].nunique() > 1
    safetail = requests[requests["method"] == results.SAFETAIL]
    assert safetail["reward"].notna().all()
    assert (safetail[safetail["phase"] == "test"]["epsilon"] == 0.0).all()


def test_three_workers_split_the_baselines_and_match(runs, tmp_path):
    report = run_experiment(tiny_config(tmp_path / "run", workers=3))
    assert report.timings_s["baselines_in_workers"] > 0.0
    assert compared_files(tmp_path / "run") == compared_files(runs[0].out_dir)


def test_inside_a_daemonic_process_everything_runs_here(runs, tmp_path, monkeypatch):
    class Daemonic:
        daemon = True

    # multiprocessing.Pool workers are daemonic and may not start processes of their own.
    monkeypatch.setattr("yafs_safetail.runs.workers.multiprocessing.current_process", Daemonic)
    report = run_experiment(tiny_config(tmp_path / "run", workers=2))
    assert report.timings_s["baselines_in_workers"] == 0.0
    assert compared_files(tmp_path / "run") == compared_files(runs[0].out_dir)


def test_a_failing_baseline_worker_fails_the_run_and_writes_nothing(tmp_path, monkeypatch):
    out = tmp_path / "run"
    out.mkdir()
    (out / "summary.md").write_text("an earlier run\n")
    (out / "requests.csv").write_text("method,phase\n")
    (out / "run.json").write_text('{"package_version": "0.1.0"}\n')

    def broken(name, edge, rng, reading):
        raise ExperimentError(f"{name}: broken on purpose")

    # Forked workers inherit the patched module.
    monkeypatch.setattr("yafs_safetail.runs.workers.make_baseline", broken)
    with pytest.raises(ExperimentError, match="Oracle: broken on purpose"):
        run_experiment(tiny_config(out, workers=2, overwrite=True))
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
    assert sorted(p.name for p in out.iterdir()) == ["requests.csv", "run.json", "summary.md"]


@pytest.mark.parametrize("servers", [3, 7])
def test_other_topologies_run(tmp_path, servers):
    topology = REPOSITORY / "topologies" / f"{servers}servers.json"
    placement = REPOSITORY / "placements" / f"{servers}servers.json"
    report = run_experiment(tiny_config(tmp_path / "run", topology=topology, placement=placement,
                                        redundancy_levels=(1, 3), write_yafs_csv=False, steps_scale=0.013))
    run = results.read_run_json(tmp_path / "run" / "run.json")
    assert run.n_servers == servers
    requests = results.read_requests_csv(tmp_path / "run" / "requests.csv")
    oracle = requests[requests["method"] == results.ORACLE]
    assert (oracle["n_selected"] == servers).all()
    assert (oracle["access_rate"] == 1.0).all()
    assert set(report.summary["method"]) == {results.SAFETAIL, *baseline_names((1, 3))}
    assert not (tmp_path / "run" / YAFS_DIR).exists()


def test_redundancy_beyond_the_servers_is_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "run"
    topology = REPOSITORY / "topologies" / "3servers.json"
    placement = REPOSITORY / "placements" / "3servers.json"
    with pytest.raises(ExperimentError, match=r"--redundancy: x=4 must be an integer in 1\.\.3"):
        run_experiment(tiny_config(out, topology=topology, placement=placement, redundancy_levels=(1, 4)))
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("workers", [0, -1, 1.0, True])
def test_bad_workers_is_refused(tmp_path, workers):
    with pytest.raises(ExperimentError, match="--workers"):
        run_experiment(tiny_config(tmp_path / "run", workers=workers))


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_bad_seed_is_refused(tmp_path, seed):
    with pytest.raises(ExperimentError, match="--seed"):
        run_experiment(tiny_config(tmp_path / "run", seed=seed))


@pytest.mark.parametrize("scale", [0.0, -1.0, math.inf, math.nan])
def test_bad_steps_scale_is_refused(tmp_path, scale):
    with pytest.raises(ExperimentError, match="--steps-scale"):
        run_experiment(tiny_config(tmp_path / "run", steps_scale=scale))


def test_checking_users_policies_leaves_the_world_as_drawn(tmp_path):
    # Vandal writes zeros into every array of the observation it gets; the check at run start
    # gives it one, and the world every method replays must not see it.
    from yafs_safetail.methods.registry import UserMethod
    from yafs_safetail.runs.experiment import _check
    from yafs_safetail.worlds.recipe import TEST, make_world

    config = tiny_config(tmp_path / "run",
                         methods=(UserMethod(f"{Path(__file__).parent / 'bad_policies.py'}:Vandal"),))
    checked = _check(config).test_world
    fresh = make_world(config, TEST)
    for step in (0, 1):
        assert checked.observation(step, checked.background_users[step]) == \
            fresh.observation(step, fresh.background_users[step])
    assert np.array_equal(checked.median_propagation_s, fresh.median_propagation_s)
    assert checked.median_propagation_s.min() > 0
