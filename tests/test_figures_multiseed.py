"""Figures across seeds with 95% bands (yafs_safetail/results/figures/multiseed.py): the data
behind each band, the bands actually drawn, the files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from results_helpers import N_SERVERS, make_run, write_run_folder, write_seed_folders

from yafs_safetail import results
from yafs_safetail.results import ResultsFileError
from yafs_safetail.results.figures import multiseed as fm

N_SEEDS = 4
BETA = 20  # results_helpers.make_run


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Four synthetic run folders of use case 1, seeds 0-3."""
    return write_seed_folders(tmp_path_factory.mktemp("bands"), N_SEEDS, 200)


@pytest.fixture(scope="module")
def series() -> fm.SeedSeries:
    run = make_run()
    return fm.SeedSeries(use_case=1, use_case_name=run.use_case_name, preset="paper",
                         seeds=tuple(range(N_SEEDS)), beta=BETA, n_servers=N_SERVERS,
                         package_version="0.1.0")


def bands_drawn(figure: Figure) -> dict[tuple[int, str], np.ndarray]:
    """(axes index, band name) -> the band polygon's vertices, found by their gid."""
    found = {}
    for index, axes in enumerate(figure.axes):
        for collection in axes.collections:
            gid = collection.get_gid()
            if gid and gid.startswith("band:"):
                assert isinstance(collection, PolyCollection)
                (path,) = collection.get_paths()
                found[(index, gid.removeprefix("band:"))] = path.vertices
    return found


def band_limits(vertices: np.ndarray, x: float) -> tuple[float, float]:
    """The lowest and highest y of a fill_between polygon at abscissa x."""
    ys = vertices[np.isclose(vertices[:, 0], x), 1]
    assert ys.size >= 2
    return float(ys.min()), float(ys.max())


# ---------------------------------------------------------------------------- the data


def test_latency_bands_are_the_bootstrap_intervals_of_the_seeds_percentiles(folders) -> None:
    bands = fm.latency_bands(results.aggregate_summaries(folders))
    summaries = [results.read_summary_csv(f) for f in folders]
    assert len(bands) == 11 * 4 and list(bands.columns) == list(fm.LATENCY_BAND_COLUMNS)
    for row in bands.itertuples(index=False):
        values = [float(s.loc[s["method"] == row.method, f"p{row.percentile}_s"].iloc[0])
                  for s in summaries]
        mean, low, high = results.bootstrap_interval(values)
        assert (row.mean_s, row.ci_low_s, row.ci_high_s, row.n_seeds) == (mean, low, high, N_SEEDS)
        # Never outside what the seeds showed, so never an impossible latency.
        assert min(values) <= row.ci_low_s <= row.mean_s <= row.ci_high_s <= max(values)
        assert row.ci_low_s < row.ci_high_s


def test_servers_bands_match_each_seeds_beta_blocks(folders) -> None:
    requests = [results.read_requests_csv(f) for f in folders]
    bands = fm.servers_bands(requests, BETA)
    # 120 training and 80 test steps, β = 20: 6 + 4 blocks.
    assert list(bands["phase"]) == ["train"] * 6 + ["test"] * 4
    assert list(bands["avg_episode"]) == [float(i) for i in range(1, 11)]
    for row in bands.itertuples(index=False):
        values = []
        for table in requests:
            rows = table[(table["method"] == "SafeTail") & (table["phase"] == row.phase)]
            block = rows.sort_values("step")["n_selected"].to_numpy(float)[
                row.block * BETA:(row.block + 1) * BETA]
            values.append(block.mean())
        mean, low, high = results.bootstrap_interval(values)
        assert row.mean == pytest.approx(mean, rel=1e-12)
        assert (row.ci_low, row.ci_high) == pytest.approx((low, high), rel=1e-12)
        # A request uses 1 to n servers: the band stays there.
        assert 1 <= min(values) <= row.ci_low <= row.ci_high <= max(values) <= N_SERVERS
        assert row.n_seeds == N_SEEDS


def test_servers_bands_of_unequal_runs_use_the_seeds_that_have_the_block(folders) -> None:
    requests = [results.read_requests_csv(f) for f in folders[:2]]
    short = requests[1]
    # Seed 1 stops testing after 40 steps: the last two test blocks have one seed, no interval.
    short = short[~((short["phase"] == "test") & (short["step"] >= 40))]
    bands = fm.servers_bands([requests[0], short], BETA).set_index(["phase", "block"])
    assert bands.loc[("test", 1), "n_seeds"] == 2 and not math.isnan(bands.loc[("test", 1), "ci_low"])
    assert bands.loc[("test", 3), "n_seeds"] == 1 and math.isnan(bands.loc[("test", 3), "ci_low"])


# ---------------------------------------------------------------------------- what is drawn


def test_latency_figure_draws_the_computed_bands(folders, series) -> None:
    bands = fm.latency_bands(results.aggregate_summaries(folders))
    figure = fm.build_latency_band_figure(bands, series, average_target_s=0.55)
    titles = [axes.get_title() for axes in figure.axes]
    assert titles == ["SafeTail vs Rand-x", "SafeTail vs MinLoad-x", "SafeTail vs MinProp-x"]
    drawn = bands_drawn(figure)
    expected_panels = {0: ["SafeTail", "Oracle", "Rand-1", "Rand-2", "Rand-3"],
                       1: ["SafeTail", "Oracle", "MinLoad-1", "MinLoad-2", "MinLoad-3"],
                       2: ["SafeTail", "Oracle", "MinProp-1", "MinProp-2", "MinProp-3"]}
    assert sorted(drawn) == sorted((i, m) for i, ms in expected_panels.items() for m in ms)
    for (index, method), vertices in drawn.items():
        part = bands[bands["method"] == method].sort_values("percentile")
        for x, row in enumerate(part.itertuples(index=False)):
            assert band_limits(vertices, x) == pytest.approx((row.ci_low_s, row.ci_high_s),
                                                             rel=1e-12)
        line = next(ln for ln in figure.axes[index].lines if ln.get_label() == method)
        assert np.allclose(line.get_ydata(), part["mean_s"].to_numpy(float), rtol=1e-12)
    targets = [ln for ln in figure.axes[0].lines if ln.get_label() == "average target"]
    assert len(targets) == 1 and targets[0].get_ydata()[0] == 0.55


def test_servers_figure_draws_the_computed_bands(folders, series) -> None:
    bands = fm.servers_bands([results.read_requests_csv(f) for f in folders], BETA)
    figure = fm.build_servers_band_figure(bands, series, boundary=6.0)
    drawn = bands_drawn(figure)
    assert sorted(drawn) == [(0, "test"), (0, "train")]
    for (_, phase), vertices in drawn.items():
        for row in bands[bands["phase"] == phase].itertuples(index=False):
            assert band_limits(vertices, row.avg_episode) == pytest.approx(
                (row.ci_low, row.ci_high), rel=1e-12)
    (axes,) = figure.axes
    assert axes.get_ylim() == (0.5, N_SERVERS + 0.5)
    assert any(list(ln.get_xdata()) == [6.0, 6.0] for ln in axes.lines)  # the train/test boundary


def test_one_seed_draws_lines_but_no_band(folders, series) -> None:
    bands = fm.latency_bands(results.aggregate_summaries(folders[:1]))
    assert bands["ci_low_s"].isna().all()
    figure = fm.build_latency_band_figure(bands, series)
    assert bands_drawn(figure) == {}
    assert any(ln.get_label() == "SafeTail" for ln in figure.axes[0].lines)


def test_runs_without_baselines_get_one_panel(series) -> None:
    stats = pd.DataFrame([
        {"method": m, "metric": f"p{p}_s", "mean": 1.0 + p / 100, "ci_low": 0.9 + p / 100,
         "ci_high": 1.1 + p / 100, "n_seeds": 2}
        for m in ("SafeTail", "Oracle") for p in results.PERCENTILES])
    figure = fm.build_latency_band_figure(fm.latency_bands(stats), series)
    assert [a.get_title() for a in figure.axes] == ["SafeTail and Oracle"]
    assert sorted(name for _, name in bands_drawn(figure)) == ["Oracle", "SafeTail"]


# ---------------------------------------------------------------------------- files


def test_files_written_and_identical_on_redraw(folders, tmp_path) -> None:
    both = ("png", "pdf")
    first = fm.draw_multiseed_figures(folders, tmp_path / "a", both)
    second = fm.draw_multiseed_figures(folders, tmp_path / "b", both)
    names = ["uc1-paper-latency-bands.png", "uc1-paper-latency-bands.pdf",
             "uc1-paper-servers-bands.png", "uc1-paper-servers-bands.pdf"]
    assert [p.name for p in first] == names
    for path, again in zip(first, second, strict=True):
        data = path.read_bytes()
        assert data.startswith(b"\x89PNG" if path.suffix == ".png" else b"%PDF")
        assert data == again.read_bytes()
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == sorted(names)  # no temporaries
    assert [p.name for p in fm.draw_multiseed_figures(folders, tmp_path / "c")] == names[::2]  # PNG


def test_mixed_use_cases_are_refused(folders, tmp_path) -> None:
    other = tmp_path / "uc2"
    write_run_folder(other, np.random.default_rng(9), use_case=2, seed=7)
    with pytest.raises(ResultsFileError, match="use_case/preset"):
        fm.draw_multiseed_figures([folders[0], other], tmp_path / "out")
    assert not (tmp_path / "out").exists()
