"""Check generated traces against the published statistics (``traces/README.md`` §7).

``python traces/generate.py --report`` prints these checks; ``tests/test_traces.py`` asserts
them. The bandwidth medians are the generator's chosen contention factors, so this module reads
them from ``generate.py`` (loaded by path: both are scripts beside the traces).
"""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.edge import published as pub


def _generator():  # noqa: ANN202 (a module loaded by path)
    path = Path(__file__).resolve().with_name("generate.py")
    spec = importlib.util.spec_from_file_location("traces_generate_choices", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


nominal_median_bps = _generator().nominal_median_bps


# ---------------------------------------------------------------- checks and report (README §7)
TOLERANCES = {
    "propagation_min_max_abs_s": 0.0005,
    "propagation_percentile_rel": 0.02,
    "propagation_p99_rel": 0.03,
    "propagation_mean_rel": 0.01,
    "bandwidth_median_rel": 0.03,
    "uc1_k1_stat_abs_s": 0.002,
    "uc1_k1_p99_abs_s": 0.005,
    "slowdown_median_rel": 0.03,
    "sigma_residual_rel": 0.10,
    "spearman_minimal_abs": 0.20,
    "spearman_moderate": (0.30, 0.75),
    "spearman_strong_min": 0.75,
    "coco_mean_bytes_rel": 0.05,
    "day_night_level_abs": 0.20,
}
"""Acceptance bands of the generated statistics; the tests and ``--report`` use these."""


@dataclass(frozen=True)
class Check:
    """One generated statistic against its published (or designed) value."""

    name: str
    measured: float
    target: str
    ok: bool


def _within_rel(measured: float, target: float, rel: float) -> bool:
    return abs(measured - target) <= rel * abs(target)


def _spearman(frame: pd.DataFrame, column: str) -> float:
    return float(frame[column].rank().corr(frame["latency_s"].rank()))


def _residual_std_by_k(frame: pd.DataFrame, gamma_columns: Sequence[str]) -> dict[int, float]:
    """Std of latency around its least-squares linear fit on Γ, per number of processes."""
    out = {}
    for k, group in frame.groupby("n_processes"):
        design = np.column_stack([np.ones(len(group))] + [group[c].to_numpy(float) for c in gamma_columns])
        coef, *_ = np.linalg.lstsq(design, group["latency_s"].to_numpy(), rcond=None)
        resid = group["latency_s"].to_numpy() - design @ coef
        out[int(k)] = float(np.std(resid, ddof=design.shape[1]))
    return out


def check_statistics(trace_dir: Path) -> list[Check]:
    """Measure the generated CSVs in ``trace_dir`` against the published figures.

    Returns:
        One Check per statistic, in README order.
    """
    # Long on purpose: one flat list of checks in the README's order, each beside its figure.
    tol = TOLERANCES
    checks: list[Check] = []

    def add(name: str, measured: float, target: str, ok: bool) -> None:
        checks.append(Check(name, float(measured), target, bool(ok)))

    prop = pd.read_csv(trace_dir / "propagation.csv")
    for condition, stats in pub.PROPAGATION_RTT_S.items():
        rtt = prop.loc[prop["condition"] == condition, "rtt_s"].to_numpy()
        for key in ("min", "max"):
            got = float(getattr(np, key)(rtt))
            add(f"propagation c{condition} {key}", got, f"{stats[key]}", abs(got - stats[key]) <= tol["propagation_min_max_abs_s"])
        for key, q in (("p10", 10), ("median", 50), ("p90", 90)):
            got = float(np.percentile(rtt, q))
            add(f"propagation c{condition} {key}", got, f"{stats[key]}", _within_rel(got, stats[key], tol["propagation_percentile_rel"]))
        got = float(np.percentile(rtt, 99))
        add(f"propagation c{condition} p99", got, f"{stats['p99']}", _within_rel(got, stats["p99"], tol["propagation_p99_rel"]))
        got = float(np.mean(rtt))
        add(f"propagation c{condition} mean", got, f"{stats['mean']}", _within_rel(got, stats["mean"], tol["propagation_mean_rel"]))

    bw = pd.read_csv(trace_dir / "bandwidth.csv")
    previous: dict[str, float] = {}
    for (level, direction), group in bw.groupby(["contention_level", "direction"]):
        nominal = nominal_median_bps(int(level), str(direction))
        got = float(group["throughput_bps"].median())
        ok = _within_rel(got, nominal, tol["bandwidth_median_rel"]) and got < previous.get(str(direction), np.inf)
        add(f"bandwidth L{level} {direction} median (falls with L)", got, f"{nominal:.4g}", ok)
        previous[str(direction)] = got

    compute = {uc: pd.read_csv(trace_dir / f"compute_uc{uc}.csv") for uc in pub.USE_CASES}
    uc1_k1 = compute[1].loc[compute[1]["n_processes"] == 1, "latency_s"].to_numpy()
    s = pub.UC1_ONE_PROCESS_S
    add("UC1 k=1 count", uc1_k1.size, f"{s['count']}", uc1_k1.size == s["count"])
    for key, value in (
        ("min", uc1_k1.min()),
        ("median", np.median(uc1_k1)),
        ("mean", uc1_k1.mean()),
        ("p90", np.percentile(uc1_k1, 90)),
        ("max", uc1_k1.max()),
    ):
        add(f"UC1 k=1 {key} s", value, f"{s[key]}", abs(value - s[key]) <= tol["uc1_k1_stat_abs_s"])
    got = float(np.percentile(uc1_k1, 99))
    add("UC1 k=1 p99 s", got, f"{s['p99']}", abs(got - s["p99"]) <= tol["uc1_k1_p99_abs_s"])
    shapes = compute[1][["height_px", "width_px"]].value_counts()
    pixels = compute[1]["width_px"] * compute[1]["height_px"]
    add("UC1 distinct resolutions", len(shapes), "19", len(shapes) == pub.UC1_RESOLUTIONS["distinct"])
    top5 = tuple(tuple(int(v) for v in hw) for hw in shapes.index[:5])
    add("UC1 five most common resolutions (1 = published order)", float(top5 == pub.UC1_RESOLUTIONS["most_common_hxw"]), "1", top5 == pub.UC1_RESOLUTIONS["most_common_hxw"])
    for key, value in (("min_pixels", pixels.min()), ("median_pixels", pixels.median()), ("max_pixels", pixels.max())):
        add(f"UC1 {key}", value, f"{pub.UC1_RESOLUTIONS[key]}", value == pub.UC1_RESOLUTIONS[key])
    mean_bytes = pub.COCO_VAL2017_TOTAL_BYTES / pub.COCO_VAL2017_IMAGES
    for uc in (1, 2):
        got = float(compute[uc]["file_bytes"].mean())
        add(f"UC{uc} mean image bytes", got, f"{mean_bytes:.0f}", _within_rel(got, mean_bytes, tol["coco_mean_bytes_rel"]))

    for uc, frame in compute.items():
        slowdown = pub.slowdown_factors(uc)
        medians = frame.groupby("n_processes")["latency_s"].median()
        for k in range(2, pub.MAX_PROCESSES + 1):
            got = float(medians[k] / medians[1])
            add(f"UC{uc} median(k={k}) / median(k=1)", got, f"s_k = {slowdown[k - 1]:.3f}", _within_rel(got, slowdown[k - 1], tol["slowdown_median_rel"]))
    for uc, gamma in ((2, ("file_bytes",)), (3, ("file_bytes", "duration_s"))):
        for k, got in _residual_std_by_k(compute[uc], gamma).items():
            target = pub.SIGMA_S[uc][k - 1]
            add(f"UC{uc} k={k} residual std s", got, f"σ_k = {target}", _within_rel(got, target, tol["sigma_residual_rel"]))

    lo_mod, hi_mod = tol["spearman_moderate"]
    minimal, strong = tol["spearman_minimal_abs"], tol["spearman_strong_min"]
    for uc, column, kind in (
        (1, "n_processes", "strong"),
        (1, "file_bytes", "minimal"),
        (1, "width_px", "minimal"),
        (1, "height_px", "minimal"),
        (2, "n_processes", "moderate"),
        (2, "file_bytes", "moderate"),
        (2, "width_px", "minimal"),
        (2, "height_px", "minimal"),
        (3, "file_bytes", "strong"),
        (3, "duration_s", "strong"),
        (3, "n_processes", "moderate"),
    ):
        rho = _spearman(compute[uc], column)
        ok = {"strong": rho >= strong, "minimal": abs(rho) < minimal, "moderate": lo_mod <= rho < hi_mod}[kind]
        add(f"UC{uc} Spearman(latency, {column})", rho, kind, ok)

    load = pd.read_csv(trace_dir / "load.csv")
    lo_ac, hi_ac = pub.LOAD_LAG1_AUTOCORR_RANGE
    for device, (lo, med, hi) in enumerate(pub.LOAD_DEVICE_MIN_MEDIAN_MAX):
        users = load[f"device_{device}"].to_numpy()
        got = (int(users.min()), float(np.median(users)), int(users.max()))
        add(f"load device_{device} min/median/max", got[1], f"{lo}/{med}/{hi} (got {got[0]}/{got[1]:g}/{got[2]})", got == (lo, med, hi))
        rho = float(np.corrcoef(users[:-1], users[1:])[0, 1])
        add(f"load device_{device} lag-1 autocorrelation", rho, f"{lo_ac}..{hi_ac}", lo_ac <= rho <= hi_ac)
        day, night = users[720:1080].mean(), users[0:360].mean()
        add(f"load device_{device} mean 12-18h > mean 0-6h", day - night, "> 0", day > night)
    levels = 1 + np.floor(4.0 * (load["device_0"] - load["device_0"].min()) / np.ptp(load["device_0"]) + 0.5)
    for key in ("night", "day"):
        minute = pub.LOAD_DAY_NIGHT_LEVELS[f"{key}_minute"]
        got = float(levels[minute : minute + 60].mean())
        target = pub.LOAD_DAY_NIGHT_LEVELS[key]
        add(f"load device_0 level 1..5, mean over hour from minute {minute}", got, f"{target}", abs(got - target) <= tol["day_night_level_abs"])
    return checks


def print_report(trace_dir: Path) -> bool:
    """Print the checks as a Markdown table (and the compute-model fit if models exist).

    Returns:
        True when every check passes.
    """
    checks = check_statistics(trace_dir)
    print("| statistic | generated | published / target | ok |")
    print("|---|---|---|---|")
    for check in checks:
        print(f"| {check.name} | {check.measured:.6g} | {check.target} | {'yes' if check.ok else 'NO'} |")
    total = sum(path.stat().st_size for path in trace_dir.glob("*.csv"))
    print(f"\nCSV total: {total} bytes; {sum(c.ok for c in checks)}/{len(checks)} checks pass.")
    models_dir = trace_dir / "models"
    fits = sorted(models_dir.glob("compute_uc*.json")) if models_dir.is_dir() else []
    if fits:
        print("\n| use case | inputs | held-out rows | R² | MAE s | residual std by k (s) |")
        print("|---|---|---|---|---|---|")
        for path in fits:
            meta = json.loads(path.read_text())
            fit = meta["fit"]
            resid = ", ".join(f"{v:.4f}" for v in meta["trace_sigma_s"])
            print(f"| {meta['use_case']} | {', '.join(meta['inputs'])} | {fit['n_test']} | {fit['r2']:.4f} | {fit['mae_s']:.4f} | {resid} |")
    return all(c.ok for c in checks)
