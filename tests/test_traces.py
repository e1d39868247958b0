"""Generated traces: statistics vs the published ones, determinism, loader validation."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from yafs_safetail.edge import published as pub
from yafs_safetail.edge.traces import (
    DEFAULT_TRACE_DIR,
    TraceError,
    load_bandwidth,
    load_compute,
    load_load_trace,
    load_propagation,
    load_traces,
    scale_load_levels,
)

CSV_NAMES = ("bandwidth.csv", "propagation.csv", "compute_uc1.csv", "compute_uc2.csv", "compute_uc3.csv", "load.csv")


def _load_script(name: str):
    spec = importlib.util.spec_from_file_location(f"traces_{name}", DEFAULT_TRACE_DIR / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve their module through sys.modules
    spec.loader.exec_module(module)
    return module


generate = _load_script("generate")
CHECKS = _load_script("check_traces").check_statistics(DEFAULT_TRACE_DIR)


@pytest.fixture(scope="module")
def traces():
    return load_traces()


@pytest.mark.parametrize("check", CHECKS, ids=[c.name for c in CHECKS])
def test_committed_statistic_within_readme_tolerance(check):
    assert check.ok, f"{check.name}: generated {check.measured:.6g}, target {check.target}"


def test_checks_cover_every_published_table():
    names = " ".join(c.name for c in CHECKS)
    for fragment in ("propagation c5 p99", "bandwidth L4", "UC1 k=1 p90", "UC3 k=5 residual", "device_9 lag-1"):
        assert fragment in names


def test_propagation_pools_match_published_table_directly(traces):
    for condition, stats in pub.PROPAGATION_RTT_S.items():
        rtt = traces.propagation.samples_s(condition)
        assert rtt.size == pub.PROPAGATION_SAMPLES_PER_CONDITION
        assert rtt.min() == pytest.approx(stats["min"], abs=5e-4)
        assert rtt.max() == pytest.approx(stats["max"], abs=5e-4)
        assert traces.propagation.median_s(condition) == pytest.approx(stats["median"], rel=0.02)
        assert rtt.mean() == pytest.approx(stats["mean"], rel=0.01)


def test_bandwidth_uncontended_is_about_20_mbit_and_drops_sharply_after_two(traces):
    bw = traces.bandwidth
    assert bw.max_contention_level == pub.MAX_CONTENTION_LEVEL
    medians = [np.median(bw.samples_bps(level, "downlink")) for level in range(5)]
    assert 19e6 <= medians[0] <= 21e6
    # Paper §III: slight change up to 2 extra devices, rapid beyond.
    assert medians[0] / medians[2] < 1.2
    assert medians[2] / medians[4] > 1.8
    assert all(len(bw.samples_bps(level, d)) == generate.BANDWIDTH_SAMPLES for level in range(5) for d in ("uplink", "downlink"))


def test_uc1_latency_independent_of_image_but_scaled_by_processes(traces):
    frame = traces.compute[1].frame
    rho = frame[["file_bytes", "latency_s"]].corr(method="spearman").iloc[0, 1]
    assert abs(rho) < 0.1
    one = frame.loc[frame.n_processes == 1, "latency_s"]
    assert len(one) == 5660
    assert one.median() == pytest.approx(0.450, abs=0.002)
    assert np.percentile(one, 90) == pytest.approx(0.514, abs=0.002)


def test_load_trace_shape_ranges_autocorrelation_and_day_night(traces):
    load = traces.load
    assert load.users.shape == (1440, 10)
    for device, (lo, med, hi) in enumerate(pub.LOAD_DEVICE_MIN_MEDIAN_MAX):
        users = load.users[:, device]
        assert (users.min(), np.median(users), users.max()) == (lo, med, hi)
        assert 0.90 <= np.corrcoef(users[:-1], users[1:])[0, 1] <= 0.998
    levels = 1 + load.levels(4)[:, 0]
    assert levels[180:240].mean() == pytest.approx(1.3, abs=0.2)
    assert levels[900:960].mean() == pytest.approx(4.8, abs=0.2)


def test_generator_is_deterministic_and_reproduces_committed_csvs(tmp_path):
    first = generate.write_csvs(2024, tmp_path / "a")
    generate.write_csvs(2024, tmp_path / "b")
    for path in first:
        again = tmp_path / "b" / path.name
        assert path.read_bytes() == again.read_bytes(), path.name
        assert path.read_bytes() == (DEFAULT_TRACE_DIR / path.name).read_bytes(), f"committed {path.name} is stale"
    generate.write_csvs(7, tmp_path / "c")
    assert (tmp_path / "c" / "load.csv").read_bytes() != (tmp_path / "a" / "load.csv").read_bytes()


def test_another_uc3_scale_changes_only_the_uc3_trace(tmp_path):
    # docs/calibration.md rule 6: UC3's one-process mean per clip is a parameter of the generator.
    written = generate.write_csvs(2024, tmp_path / "s", uc3_mean_latency_s=0.5)
    for path in written:
        same = path.read_bytes() == (DEFAULT_TRACE_DIR / path.name).read_bytes()
        assert same is (path.name != "compute_uc3.csv"), path.name
    uc3 = pd.read_csv(tmp_path / "s" / "compute_uc3.csv")
    one_process = uc3[uc3["n_processes"] == 1]["latency_s"]
    assert abs(one_process.mean() - 0.5) < 0.01


@pytest.mark.parametrize("argv", [["--uc3-mean-latency-s", "-1"], ["--seed", "x"]])
def test_the_generator_refuses_bad_input_in_one_line_writing_nothing(tmp_path, capsys, argv):
    from yafs_safetail.cli import EXIT_BAD_INPUT, run_cli

    assert run_cli(generate.main, ["--out", str(tmp_path / "out"), *argv]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert not (tmp_path / "out").exists()


def test_generated_csvs_are_small():
    total = sum((DEFAULT_TRACE_DIR / name).stat().st_size for name in CSV_NAMES)
    assert total < 3_000_000


def test_power_quantile_function_hits_knots_and_mean():
    probs, values = (0.0, 0.5, 1.0), (1.0, 2.0, 4.0)
    quantile, gamma = generate.power_quantile_function(probs, values, mean=2.0)
    assert quantile(np.array([0.0, 0.5, 1.0])) == pytest.approx([1.0, 2.0, 4.0])
    u = (np.arange(200_000) + 0.5) / 200_000
    assert quantile(u).mean() == pytest.approx(2.0, rel=1e-4)
    assert gamma > 1.0
    with pytest.raises(ValueError, match="unreachable"):
        generate.power_quantile_function(probs, values, mean=5.0)


def test_slowdown_factors_use_published_ratios_then_cpu_share():
    s = pub.slowdown_factors(1)
    assert s[:3] == pytest.approx((1.0, 216.1 / 133.8, 291.8 / 133.8))
    assert s[2] < s[3] < s[4]
    with pytest.raises(ValueError, match="use_case"):
        pub.slowdown_factors(4)


# ----------------------------------------------------------------------------- scaling


def test_scale_load_levels_min_max_and_half_up_rounding():
    users = np.array([[0, 5], [1, 5], [2, 5], [4, 5], [8, 5]])
    levels = scale_load_levels(users, max_level=4)
    # 1/8 * 4 = 0.5 rounds up to 1; a constant device maps to 0.
    assert levels[:, 0].tolist() == [0, 1, 1, 2, 4]
    assert levels[:, 1].tolist() == [0, 0, 0, 0, 0]
    assert scale_load_levels(users[:, 0], 2).tolist() == [0, 0, 1, 1, 2]
    with pytest.raises(ValueError, match="max_level"):
        scale_load_levels(users, 0)


# ----------------------------------------------------------------------------- validation


def _write(tmp_path: Path, name: str, frame: pd.DataFrame) -> Path:
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def _bandwidth_frame() -> pd.DataFrame:
    return pd.DataFrame(
        {"contention_level": [0, 0, 1, 1], "direction": ["uplink", "downlink"] * 2, "throughput_bps": [2e7, 2e7, 1e7, 1e7]}
    )


def test_missing_file_names_the_file(tmp_path):
    with pytest.raises(TraceError, match="bandwidth.csv: trace file not found"):
        load_bandwidth(tmp_path / "bandwidth.csv")
    with pytest.raises(TraceError, match="trace directory not found"):
        load_traces(tmp_path / "nowhere")


def test_missing_column_names_file_and_column(tmp_path):
    path = _write(tmp_path, "bandwidth.csv", _bandwidth_frame().drop(columns="direction"))
    with pytest.raises(TraceError, match=r"bandwidth.csv: missing column 'direction'"):
        load_bandwidth(path)


@pytest.mark.parametrize(
    ("value", "message"),
    [(np.nan, "NaN/empty is not a finite number"), (-1.0, "-1 must be > 0"), ("fast", "'fast'")],
)
def test_bad_bandwidth_value_names_column_and_row(tmp_path, value, message):
    frame = _bandwidth_frame().astype({"throughput_bps": object})
    frame.loc[1, "throughput_bps"] = value
    path = _write(tmp_path, "bandwidth.csv", frame)
    # Data row 2 is the file's row 3, as a spreadsheet shows it (the header is row 1).
    with pytest.raises(TraceError, match=re.escape(f"bandwidth.csv: row 3 (header = row 1), column 'throughput_bps': {message}")):
        load_bandwidth(path)


@pytest.mark.parametrize(
    ("lines", "message"),
    [(["1,0.05", "2", "3,0.1"], "row 3 (header = row 1), column 'rtt_s': NaN/empty is not a finite number"),
     (["1,0.05", "2,0.1,7", "3,0.1"], "row 3 (header = row 1): 3 values, the header has 2 columns"),
     (["1,0.05", "", "3,0.1"], "row 3 (header = row 1), column 'condition': NaN/empty is not a finite number"),
     (["1,0.05", "2,0.1", "3,-0.2"], "row 4 (header = row 1), column 'rtt_s': -0.2 must be > 0"),
     (["1,0.05", "2,0.1", "3,slow"], "row 4 (header = row 1), column 'rtt_s': 'slow' is not a finite number")],
)
def test_bad_row_is_named_as_a_spreadsheet_shows_it(tmp_path, lines, message):
    """A missing value, an extra one, a blank line, a negative or non-numeric time: one line
    naming the file, the row (the header is row 1, as in a spreadsheet) and the column."""
    path = tmp_path / "propagation.csv"
    path.write_text("\n".join(["condition,rtt_s", *lines, "4,0.1", "5,0.1", "", ""]))
    with pytest.raises(TraceError) as raised:
        load_propagation(path)
    assert str(raised.value) == f"{path}: {message}"


def test_bandwidth_unknown_direction_and_missing_level(tmp_path):
    frame = _bandwidth_frame()
    frame.loc[2, "direction"] = "sideways"
    with pytest.raises(TraceError, match=r"row 4 \(header = row 1\), column 'direction': 'sideways'"):
        load_bandwidth(_write(tmp_path, "bandwidth.csv", frame))
    frame = _bandwidth_frame()
    frame.loc[[2, 3], "contention_level"] = 2
    with pytest.raises(TraceError, match="no uplink rows for level 1"):
        load_bandwidth(_write(tmp_path, "bandwidth.csv", frame))


def test_bandwidth_pool_lookup_errors(traces):
    with pytest.raises(TraceError, match="contention_level 5 outside 0..4"):
        traces.bandwidth.samples_bps(5, "uplink")
    with pytest.raises(TraceError, match="direction 'up'"):
        traces.bandwidth.samples_bps(0, "up")


def test_propagation_unknown_condition_in_file_and_lookup(tmp_path, traces):
    frame = pd.DataFrame({"condition": [1, 2, 3, 4, 5, 6], "rtt_s": [0.05] * 6})
    with pytest.raises(TraceError, match=r"propagation.csv: row 7 \(header = row 1\), column 'condition': 6 is not one of"):
        load_propagation(_write(tmp_path, "propagation.csv", frame))
    frame = pd.DataFrame({"condition": [1, 2, 3, 4], "rtt_s": [0.05] * 4})
    with pytest.raises(TraceError, match="no rows for condition 5"):
        load_propagation(_write(tmp_path, "propagation.csv", frame))
    with pytest.raises(TraceError, match="condition 9 unknown"):
        traces.propagation.samples_s(9)


def _compute_frame() -> pd.DataFrame:
    k = np.arange(1, 6)
    return pd.DataFrame({"file_bytes": 96044, "duration_s": 3.0, "n_processes": k, "latency_s": 4.0 + 0.1 * k})


def test_compute_validation(tmp_path):
    frame = _compute_frame()
    frame.loc[0, "n_processes"] = 6
    with pytest.raises(TraceError, match=r"compute_uc3.csv: row 2 \(header = row 1\), column 'n_processes': 6 outside 1..5"):
        load_compute(_write(tmp_path, "compute_uc3.csv", frame), 3)
    frame = _compute_frame().astype({"n_processes": float})
    frame.loc[3, "n_processes"] = 2.5
    with pytest.raises(TraceError, match=r"row 5 \(header = row 1\), column 'n_processes': 2.5 is not an integer"):
        load_compute(_write(tmp_path, "compute_uc3.csv", frame), 3)
    frame = _compute_frame()
    frame.loc[4, "n_processes"] = 1
    with pytest.raises(TraceError, match=r"no rows for k = \[5\]"):
        load_compute(_write(tmp_path, "compute_uc3.csv", frame), 3)
    frame = _compute_frame()
    frame.loc[2, "latency_s"] = 0.0
    with pytest.raises(TraceError, match=r"row 4 \(header = row 1\), column 'latency_s': 0 must be > 0"):
        load_compute(_write(tmp_path, "compute_uc3.csv", frame), 3)
    with pytest.raises(TraceError, match="missing column 'width_px'"):
        load_compute(_write(tmp_path, "compute_uc3.csv", _compute_frame()), 1)
    with pytest.raises(TraceError, match="use_case 4"):
        load_compute(tmp_path / "compute_uc3.csv", 4)
    trace = load_compute(_write(tmp_path, "compute_uc3.csv", _compute_frame()), 3)
    assert trace.gamma_matrix().shape == (5, 2)
    assert trace.n_processes.tolist() == [1, 2, 3, 4, 5]


def test_load_trace_validation(tmp_path):
    frame = pd.DataFrame({"minute": [0, 1, 2], "device_0": [1, 2, 3], "device_1": [0, 0, 1]})
    assert load_load_trace(_write(tmp_path, "load.csv", frame)).users.shape == (3, 2)
    bad = frame.assign(minute=[0, 2, 1])
    with pytest.raises(TraceError, match=r"row 3 \(header = row 1\), column 'minute': 2, expected 1"):
        load_load_trace(_write(tmp_path, "load.csv", bad))
    bad = frame.assign(device_1=[0, -1, 1])
    with pytest.raises(TraceError, match=r"row 3 \(header = row 1\), column 'device_1': -1 must be >= 0"):
        load_load_trace(_write(tmp_path, "load.csv", bad))
    with pytest.raises(TraceError, match="no 'device_N' columns"):
        load_load_trace(_write(tmp_path, "load.csv", frame[["minute"]]))


def test_empty_and_unreadable_files(tmp_path):
    path = tmp_path / "load.csv"
    path.write_text("")
    with pytest.raises(TraceError, match="load.csv: not a readable CSV"):
        load_load_trace(path)
    path.write_text("minute,device_0\n")
    with pytest.raises(TraceError, match="load.csv: no data rows"):
        load_load_trace(path)


def test_loaded_arrays_are_read_only(traces):
    with pytest.raises(ValueError):
        traces.load.users[0, 0] = 99
    with pytest.raises(ValueError):
        traces.propagation.samples_s(1)[0] = 0.0
