"""One run's figures (yafs_safetail.results.figures.run_figures): files drawn from a results
folder, and its command (commands/figures.py) on bad input."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
from test_results import make_requests, make_run, write_run_folder

from yafs_safetail import results
from yafs_safetail.commands import figures as figures_command
from yafs_safetail.defaults import FIGURE_FORMATS
from yafs_safetail.results.figures import run_figures as figures

FIGURE_FILES = sorted(f"{stem}.{fmt}" for stem in figures.FIGURE_STEMS.values()
                      for fmt in FIGURE_FORMATS)


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "yafs_safetail.commands.figures", *args],
                          capture_output=True, text=True, timeout=120, check=False)


@pytest.fixture(scope="module")
def drawn_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("run")
    write_run_folder(folder, np.random.default_rng(21))
    written = figures.draw_figures(folder, formats=FIGURE_FORMATS)
    return folder, written


def test_every_panel_written_as_png_and_pdf(drawn_folder):
    folder, written = drawn_folder
    assert sorted(p.name for p in written) == FIGURE_FILES
    assert sorted(p.name for p in (folder / "figures").iterdir()) == FIGURE_FILES
    for path in written:
        data = path.read_bytes()
        assert len(data) > 5000, path.name
        assert data.startswith(b"\x89PNG" if path.suffix == ".png" else b"%PDF"), path.name


def test_figures_are_deterministic(drawn_folder):
    folder, written = drawn_folder
    before = {p.name: p.read_bytes() for p in written}
    again = figures.draw_figures(folder, formats=FIGURE_FORMATS)
    assert {p.name: p.read_bytes() for p in again} == before


def test_run_without_a_baseline_family(tmp_path):
    requests = make_requests(np.random.default_rng(22), n_train=40, n_test=40,
                             methods=("SafeTail", "Oracle", "Rand-1"))
    results.write_requests_csv(requests, tmp_path)
    run = results.RunMetadata(
        use_case=3, use_case_name="audio noise removal", preset="tuned", seed=4, n_servers=5,
        beta=10, train_steps=40, test_steps=40, topology="t.json",
        methods=["SafeTail", "Oracle", "Rand-1"], package_version="0.1.0", command="test")
    written = figures.draw_figures(tmp_path, requests, run)
    assert sorted(p.name for p in written) == [f for f in FIGURE_FILES if f.endswith(".png")]
    assert not (tmp_path / "run.json").exists()  # drawn from the given tables alone


def test_figure_contents():
    requests = make_requests(np.random.default_rng(24), n_train=60, n_test=40)
    run = make_run(use_case=2, beta=20)
    run.preset = "tuned"
    built = figures.build_figures(requests, run)
    assert set(built) == {*"abcdefg", "energy", "cdf"}
    starts = {"energy": "p99 latency against energy", "cdf": "Latency CDF, test phase"}
    for panel, figure in built.items():
        title = figure.axes[0].get_title()
        assert title.startswith(starts.get(panel, f"({panel})"))
        assert "use case 2" in title and "preset tuned" in title
    # A requests table without energy columns (written before them): the figure says so.
    assert "no energy columns" in built["energy"].axes[0].get_title()
    legend = {t.get_text() for t in built["a"].axes[0].get_legend().get_texts()}
    assert legend == {"SafeTail", "Oracle", "Rand-1", "MinLoad-1", "MinProp-1", "average target"}
    target_line = built["a"].axes[0].get_lines()[0]
    mean_target = requests.query("method == 'SafeTail' and phase == 'test'")["target_s"].mean()
    assert target_line.get_ydata()[0] == pytest.approx(mean_target)
    legend_b = [t.get_text() for t in built["b"].axes[0].get_legend().get_texts()]
    assert legend_b == ["SafeTail", "Rand-1", "Rand-2", "Rand-3"]
    safetail_bars = built["b"].axes[0].containers[0]
    summary = results.summarize(requests)
    expected = summary.iloc[0][["p50_s", "p90_s", "p95_s", "p99_s"]].astype(float).to_numpy()
    np.testing.assert_allclose([bar.get_height() for bar in safetail_bars], expected)
    lines_e = built["e"].axes[0].get_lines()
    train_curve = [ln for ln in lines_e if ln.get_label() == "training"][0]
    np.testing.assert_allclose(train_curve.get_xdata(), [1, 2, 3])
    boundary = [ln for ln in lines_e if ln.get_linestyle() == ":"][0]
    assert boundary.get_xdata()[0] == pytest.approx(3.0)


def test_latency_cdf_has_every_methods_test_latencies_and_the_target():
    requests = make_requests(np.random.default_rng(25), n_train=30, n_test=50)
    axes = figures.build_figures(requests, make_run())["cdf"].axes[0]
    test = requests[requests["phase"] == "test"]
    curves = {line.get_label(): line for line in axes.get_lines() if not line.get_label().startswith("avg.")}
    assert list(curves) == results.sort_methods(set(test["method"]))
    for method, line in curves.items():
        latencies_s = np.sort(test.loc[test["method"] == method, "latency_s"].to_numpy(float))
        np.testing.assert_allclose(line.get_xdata(), latencies_s)  # the test phase's, every one
        share = np.asarray(line.get_ydata())
        assert share[-1] == pytest.approx(1.0) and np.all(np.diff(share) > 0)
    (target,) = [line for line in axes.get_lines() if line.get_label().startswith("avg. target")]
    mean_target = test.loc[test["method"] == "SafeTail", "target_s"].mean()
    assert target.get_xdata()[0] == pytest.approx(mean_target)
    assert axes.get_xscale() == "log"
    # SafeTail drawn over the others (it often runs along Oracle's curve).
    assert curves["SafeTail"].get_zorder() > max(line.get_zorder() for m, line in curves.items() if m != "SafeTail")


def test_cli_redraws(drawn_folder):
    folder, _ = drawn_folder
    done = run_cli(str(folder))
    assert done.returncode == 0, done.stderr
    assert f"wrote {len(figures.FIGURE_STEMS)} files" in done.stdout  # PNG only unless asked


def test_quiet_prints_only_the_figures_folder(drawn_folder, capsys):
    folder, _ = drawn_folder
    assert figures_command.main([str(folder), "--quiet"]) == 0
    assert capsys.readouterr().out == f"{folder / figures.FIGURES_DIR}\n"


def _break_column(folder):
    frame = results.read_requests_csv(folder).drop(columns=["deviation_s"])
    frame.to_csv(folder / "requests.csv", index=False)


def _garble(folder):
    (folder / "requests.csv").write_bytes(b'method,phase\n"SafeTail,train\n\x00\xff\xfe')


def _bad_value(folder):
    frame = results.read_requests_csv(folder)
    frame.loc[3, "latency_s"] = -1.0
    frame.to_csv(folder / "requests.csv", index=False)


def _bad_run(folder):
    data = json.loads((folder / "run.json").read_text())
    del data["preset"]
    (folder / "run.json").write_text(json.dumps(data))


@pytest.mark.parametrize(
    ("spoil", "needles"),
    [
        (lambda f: (f / "requests.csv").unlink(), ["requests.csv", "not found"]),
        (_break_column, ["requests.csv", "deviation_s"]),
        (_garble, ["requests.csv"]),
        (_bad_value, ["requests.csv", "latency_s", "line 5"]),
        (_bad_run, ["run.json", "preset"]),
    ],
)
def test_cli_bad_input_keeps_existing_figures(tmp_path, drawn_folder, spoil, needles):
    source, _ = drawn_folder
    shutil.copytree(source, tmp_path, dirs_exist_ok=True)
    before = {p.name: p.read_bytes() for p in (tmp_path / "figures").iterdir()}
    assert len(before) == len(FIGURE_FILES)
    spoil(tmp_path)
    done = run_cli(str(tmp_path))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    for needle in needles:
        assert needle in lines[0]
    after = {p.name: p.read_bytes() for p in (tmp_path / "figures").iterdir()}
    assert after == before  # nothing deleted, changed or left half-written


def test_cli_missing_folder(tmp_path):
    done = run_cli(str(tmp_path / "nowhere"))
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"error: {tmp_path / 'nowhere'}: results folder not found"]
    assert not (tmp_path / "nowhere").exists()


def test_cli_draws_only_the_asked_format(tmp_path, drawn_folder):
    source, _ = drawn_folder
    shutil.copyfile(source / "requests.csv", tmp_path / "requests.csv")
    shutil.copyfile(source / "run.json", tmp_path / "run.json")
    done = run_cli(str(tmp_path), "--figure-format", "png")
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in (tmp_path / "figures").iterdir()) == sorted(
        f"{stem}.png" for stem in figures.FIGURE_STEMS.values())


def test_cli_rejects_an_unknown_format(tmp_path, drawn_folder):
    source, _ = drawn_folder
    done = run_cli(str(source), "--figure-format", "png,svg")
    assert done.returncode == 2
    assert "--figure-format" in done.stderr and "'png,svg'" in done.stderr
    assert "Traceback" not in done.stderr
