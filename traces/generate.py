"""Generate the project's synthetic traces from the published statistics.

The paper's measured traces were never published; this script rebuilds traces with the
published statistics (``yafs_safetail/edge/published.py``, sourced from facts.md) and the
documented choices of ``traces/README.md``. Same seed -> byte-identical CSVs.

Usage::

    python traces/generate.py --seed 2024 --out traces/          # CSVs + compute models
    python traces/generate.py --seed 2024 --out /tmp/t --no-models
    python traces/generate.py --report --out traces/             # measured vs published
    python traces/generate.py --out /tmp/t --uc3-mean-latency-s 0.5   # another UC3 scale (rule 6)
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.cli import ArgumentParser, run_cli
from yafs_safetail.edge import published as pub

DEFAULT_SEED = 2024

# ---------------------------------------------------------------- bandwidth (choices, README §2)
BANDWIDTH_SAMPLES = 1000
DOWNLINK_MEDIAN_BPS = pub.UNCONTENDED_BANDWIDTH_BPS
UPLINK_TO_DOWNLINK = 0.95
# Index = extra contending devices. Paper §III: latency rises only slightly up to 2 extra
# devices, then rapidly; throughput is its inverse, so the factor drops gently then steeply.
CONTENTION_MEDIAN_FACTOR = (1.00, 0.95, 0.88, 0.62, 0.40)
CONTENTION_LOG_SIGMA = (0.06, 0.08, 0.11, 0.18, 0.25)
# Share of iperf3 runs hit by a retry/collision burst, and the throughput kept in such a run.
CONTENTION_DIP_PROBABILITY = (0.02, 0.03, 0.05, 0.10, 0.15)
DIP_FACTOR_RANGE = (0.3, 0.8)

# ---------------------------------------------------------------- compute (choices, README §4)
UC1_P10_S = 0.400
COMPUTE_ROWS_PER_K = 1500
# 19 YOLOv5 letterboxed shapes (height, width), multiples of 32 with the long side 640, and
# their shares; the five most common are the published ones, in the published order.
UC1_SHAPES_HW_SHARE = (
    ((480, 640), 0.38),
    ((448, 640), 0.14),
    ((640, 480), 0.10),
    ((640, 448), 0.06),
    ((640, 640), 0.05),
    ((288, 640), 0.018),
    ((320, 640), 0.018),
    ((352, 640), 0.018),
    ((384, 640), 0.018),
    ((416, 640), 0.018),
    ((640, 320), 0.017),
    ((640, 352), 0.017),
    ((640, 384), 0.018),
    ((640, 416), 0.018),
    ((512, 640), 0.024),
    ((544, 640), 0.022),
    ((576, 640), 0.022),
    ((640, 512), 0.022),
    ((640, 576), 0.020),
)
JPEG_BYTES_PER_PIXEL_LOG_SIGMA = 0.45
UC2_FIXED_SHARE = 0.05
AUDIO_SAMPLE_RATE_HZ = 16_000
AUDIO_DURATION_MEDIAN_S = 3.5
AUDIO_DURATION_LOG_SIGMA = 0.30
AUDIO_DURATION_RANGE_S = (1.0, 10.0)
UC3_FIXED_SHARE = 0.10

# ---------------------------------------------------------------- load (choices, README §5)
# Per device: (diurnal weight, AR(1) coefficient, peak minute). Device 0 carries the published
# day/night figure, so its diurnal component dominates.
LOAD_DEVICE_SHAPE = (
    (2.0, 0.95, 900),
    (2.0, 0.995, 870),
    (1.5, 0.99, 930),
    (2.0, 0.98, 840),
    (1.0, 0.995, 900),
    (1.5, 0.985, 960),
    (1.2, 0.99, 900),
    (2.0, 0.98, 870),
    (1.8, 0.99, 930),
    (1.0, 0.995, 880),
)

LATENCY_DECIMALS = 4  # 0.1 ms
RTT_DECIMALS = 4


def power_quantile_function(
    probs: Sequence[float], values: Sequence[float], mean: float
) -> tuple[Callable[[np.ndarray], np.ndarray], float]:
    """Build a quantile function through published percentiles that also has a given mean.

    Between consecutive knots (p_i, v_i) the function is v_i + (v_{i+1} - v_i) * t**γ with t the
    position inside the segment. One γ for all segments; the mean of t**γ on [0, 1] is
    1 / (1 + γ), so the overall mean is base + spread / (1 + γ) and γ has a closed form.

    Args:
        probs: knot probabilities, increasing from 0 to 1.
        values: knot values, non-decreasing.
        mean: the required mean.

    Returns:
        (q, γ) with q mapping uniforms in [0, 1] to values.
    """
    p = np.asarray(probs, dtype=float)
    v = np.asarray(values, dtype=float)
    width = np.diff(p)
    base = float(np.sum(width * v[:-1]))
    spread = float(np.sum(width * np.diff(v)))
    if not base < mean < base + spread:
        raise ValueError(f"mean {mean} unreachable between {base} and {base + spread}")
    gamma = spread / (mean - base) - 1.0

    def quantile(u: np.ndarray) -> np.ndarray:
        seg = np.clip(np.searchsorted(p, u, side="right") - 1, 0, len(p) - 2)
        t = (u - p[seg]) / (p[seg + 1] - p[seg])
        return v[seg] + (v[seg + 1] - v[seg]) * np.power(t, gamma)

    return quantile, gamma


def stratified_uniforms(rng: np.random.Generator, n: int) -> np.ndarray:
    """n uniforms, one per stratum [i/n, (i+1)/n), with the extremes pinned to 0 and 1.

    Pinning makes a finite pool reach the published min and max exactly; stratifying keeps its
    percentiles within one stratum of the target. Returned in random order.
    """
    u = (np.arange(n) + rng.random(n)) / n
    u[0], u[-1] = 0.0, 1.0
    return rng.permutation(u)


def _mixture_cdf(x: float, sigma: float, dip_probability: float) -> float:
    """CDF at x of exp(σZ) times, with probability p, a U(DIP_FACTOR_RANGE) factor."""
    lo, hi = DIP_FACTOR_RANGE
    dip_factors = lo + (hi - lo) * (np.arange(400) + 0.5) / 400

    def normal_cdf(z: np.ndarray) -> np.ndarray:
        return 0.5 * (1.0 + np.vectorize(math.erf)(z / math.sqrt(2.0)))

    clean = float(normal_cdf(np.array(math.log(x) / sigma)))
    dipped = float(np.mean(normal_cdf(np.log(x / dip_factors) / sigma)))
    return (1.0 - dip_probability) * clean + dip_probability * dipped


def lognormal_scale_for_median(sigma: float, dip_probability: float) -> float:
    """Factor m such that the dip mixture scaled by m has median 1 (bisection on its CDF)."""
    lo, hi = 0.5, 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _mixture_cdf(1.0 / mid, sigma, dip_probability) > 0.5:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def nominal_median_bps(level: int, direction: str) -> float:
    """Designed median throughput of one (contention level, direction) pool."""
    scale = UPLINK_TO_DOWNLINK if direction == "uplink" else 1.0
    return DOWNLINK_MEDIAN_BPS * scale * CONTENTION_MEDIAN_FACTOR[level]


def generate_bandwidth(rng: np.random.Generator) -> pd.DataFrame:
    rows = []
    for level in range(pub.MAX_CONTENTION_LEVEL + 1):
        sigma, dip_p = CONTENTION_LOG_SIGMA[level], CONTENTION_DIP_PROBABILITY[level]
        for direction in ("uplink", "downlink"):
            scale_bps = nominal_median_bps(level, direction) * lognormal_scale_for_median(sigma, dip_p)
            bps = scale_bps * np.exp(sigma * rng.standard_normal(BANDWIDTH_SAMPLES))
            dip = rng.random(BANDWIDTH_SAMPLES) < dip_p
            bps[dip] *= rng.uniform(*DIP_FACTOR_RANGE, size=int(dip.sum()))
            rows.append(
                pd.DataFrame(
                    {"contention_level": level, "direction": direction, "throughput_bps": np.rint(bps).astype(np.int64)}
                )
            )
    return pd.concat(rows, ignore_index=True)


def generate_propagation(rng: np.random.Generator) -> pd.DataFrame:
    probs = (0.0, 0.10, 0.50, 0.90, 0.99, 1.0)
    frames = []
    for condition, stats in pub.PROPAGATION_RTT_S.items():
        values = [stats[k] for k in ("min", "p10", "median", "p90", "p99", "max")]
        quantile, _ = power_quantile_function(probs, values, stats["mean"])
        rtt = quantile(stratified_uniforms(rng, pub.PROPAGATION_SAMPLES_PER_CONDITION))
        frames.append(pd.DataFrame({"condition": condition, "rtt_s": np.round(rtt, RTT_DECIMALS)}))
    return pd.concat(frames, ignore_index=True)


def uc1_quantile_function() -> Callable[[np.ndarray], np.ndarray]:
    s = pub.UC1_ONE_PROCESS_S
    quantile, _ = power_quantile_function(
        (0.0, 0.10, 0.50, 0.90, 0.99, 1.0),
        (s["min"], UC1_P10_S, s["median"], s["p90"], s["p99"], s["max"]),
        s["mean"],
    )
    return quantile


def coco_images(rng: np.random.Generator, n: int) -> pd.DataFrame:
    """COCO-like images: a letterboxed shape and a JPEG size with mean ~157.6 KB."""
    shapes = np.array([hw for hw, _ in UC1_SHAPES_HW_SHARE])
    share = np.array([w for _, w in UC1_SHAPES_HW_SHARE])
    share = share / share.sum()
    pick = rng.choice(len(shapes), size=n, p=share)
    height, width = shapes[pick, 0], shapes[pick, 1]
    mean_pixels = float(np.sum(share * shapes[:, 0] * shapes[:, 1]))
    mean_bytes = pub.COCO_VAL2017_TOTAL_BYTES / pub.COCO_VAL2017_IMAGES
    sigma = JPEG_BYTES_PER_PIXEL_LOG_SIGMA
    bpp_median = mean_bytes / mean_pixels / np.exp(sigma**2 / 2)
    bpp = bpp_median * np.exp(sigma * rng.standard_normal(n))
    return pd.DataFrame(
        {
            "file_bytes": np.rint(height * width * bpp).astype(np.int64),
            "width_px": width.astype(np.int64),
            "height_px": height.astype(np.int64),
        }
    )


def uc1_batch_size() -> float:
    """Images in the published UC1 batch: its one-process wall time over the mean latency."""
    return pub.BATCH_WALL_TIME_S[1][0] / pub.UC1_ONE_PROCESS_S["mean"]


def uc2_mean_latency_s() -> float:
    """UC2 one-process mean: same image batch as UC1, so wall time / batch size."""
    return pub.BATCH_WALL_TIME_S[2][0] / uc1_batch_size()


def uc3_mean_latency_s() -> float:
    """UC3 one-process mean from the σ_1 / mean ratio UC1 and UC2 share (README §4.3): 4.17 s,
    the shipped trace's. docs/calibration.md rule 6 tried others (``--uc3-mean-latency-s``)."""
    ratio = 0.5 * (pub.SIGMA_S[1][0] / pub.UC1_ONE_PROCESS_S["mean"] + pub.SIGMA_S[2][0] / uc2_mean_latency_s())
    return pub.SIGMA_S[3][0] / ratio


def generate_compute_uc1(rng: np.random.Generator) -> pd.DataFrame:
    quantile = uc1_quantile_function()
    slowdown = pub.slowdown_factors(1)
    frames = []
    rows_per_k = (int(pub.UC1_ONE_PROCESS_S["count"]),) + (COMPUTE_ROWS_PER_K,) * (pub.MAX_PROCESSES - 1)
    for k, n in enumerate(rows_per_k, start=1):
        images = coco_images(rng, n)
        # k = 1 is the published distribution (stratified); k > 1 scales it by s_k, independent of
        # the image: the paper finds UC1 latency uncorrelated with file size and resolution.
        u = stratified_uniforms(rng, n) if k == 1 else rng.random(n)
        images["n_processes"] = k
        images["latency_s"] = np.round(slowdown[k - 1] * quantile(u), LATENCY_DECIMALS)
        frames.append(images)
    return pd.concat(frames, ignore_index=True)


def generate_compute_uc2(rng: np.random.Generator) -> pd.DataFrame:
    slowdown = pub.slowdown_factors(2)
    mean_s = uc2_mean_latency_s()
    mean_bytes = pub.COCO_VAL2017_TOTAL_BYTES / pub.COCO_VAL2017_IMAGES
    per_byte_s = (1.0 - UC2_FIXED_SHARE) * mean_s / mean_bytes
    # Every k replays the same images, as a batch run with k processes does.
    images = coco_images(rng, COMPUTE_ROWS_PER_K)
    one_process_s = UC2_FIXED_SHARE * mean_s + per_byte_s * images["file_bytes"].to_numpy()
    frames = []
    for k in range(1, pub.MAX_PROCESSES + 1):
        noise_s = pub.SIGMA_S[2][k - 1] * rng.standard_normal(len(images))
        frame = images.copy()
        frame["n_processes"] = k
        frame["latency_s"] = np.round(slowdown[k - 1] * one_process_s + noise_s, LATENCY_DECIMALS)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def generate_compute_uc3(rng: np.random.Generator, mean_s: float | None = None) -> pd.DataFrame:
    """UC3's compute trace; ``mean_s`` the one-process mean per clip (None: the shipped
    trace's, :func:`uc3_mean_latency_s`; docs/calibration.md rule 6's grid tried others)."""
    slowdown = pub.slowdown_factors(3)
    lo, hi = AUDIO_DURATION_RANGE_S
    duration = AUDIO_DURATION_MEDIAN_S * np.exp(AUDIO_DURATION_LOG_SIGMA * rng.standard_normal(COMPUTE_ROWS_PER_K))
    samples = np.rint(np.clip(duration, lo, hi) * AUDIO_SAMPLE_RATE_HZ).astype(np.int64)
    duration_s = samples / AUDIO_SAMPLE_RATE_HZ
    mean_s = uc3_mean_latency_s() if mean_s is None else mean_s
    # The per-second cost is set so the one-process mean over the clips is the derived UC3 mean.
    per_audio_second_s = (1.0 - UC3_FIXED_SHARE) * mean_s / float(duration_s.mean())
    one_process_s = UC3_FIXED_SHARE * mean_s + per_audio_second_s * duration_s
    bytes_per_sample = pub.AUDIO_BYTES_PER_S // AUDIO_SAMPLE_RATE_HZ
    frames = []
    for k in range(1, pub.MAX_PROCESSES + 1):
        noise_s = pub.SIGMA_S[3][k - 1] * rng.standard_normal(samples.size)
        frames.append(
            pd.DataFrame(
                {
                    "file_bytes": pub.WAV_HEADER_BYTES + samples * bytes_per_sample,
                    "duration_s": duration_s,
                    "n_processes": k,
                    "latency_s": np.round(slowdown[k - 1] * one_process_s + noise_s, LATENCY_DECIMALS),
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def _ar1(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    """Stationary unit-variance AR(1) path."""
    innovation = rng.standard_normal(n) * np.sqrt(1.0 - phi**2)
    x = np.empty(n)
    x[0] = rng.standard_normal()
    for t in range(1, n):
        x[t] = phi * x[t - 1] + innovation[t]
    return x


def _rank_to_counts(latent: np.ndarray, lo: int, median: int, hi: int) -> np.ndarray:
    """Map a latent path monotonically onto integers with an exact min, median and max.

    Each minute's rank fraction goes through the piecewise-linear quantile function
    (0, lo) - (0.5, median) - (1, hi); rounding is half-up. The two middle ranks are set to the
    median so the 1,440-row median is exactly the published one.
    """
    n = latent.size
    order = np.argsort(latent, kind="stable")
    fraction = np.linspace(0.0, 1.0, n)
    values = np.interp(fraction, [0.0, 0.5, 1.0], [lo, median, hi])
    counts_sorted = np.floor(values + 0.5).astype(np.int64)
    counts_sorted[n // 2 - 1 : n // 2 + 1] = median
    counts = np.empty(n, dtype=np.int64)
    counts[order] = counts_sorted
    return counts


def generate_load(rng: np.random.Generator) -> pd.DataFrame:
    minute = np.arange(pub.LOAD_MINUTES)
    data: dict[str, np.ndarray] = {"minute": minute}
    for device, ((lo, med, hi), (weight, phi, peak)) in enumerate(
        zip(pub.LOAD_DEVICE_MIN_MEDIAN_MAX, LOAD_DEVICE_SHAPE, strict=True)
    ):
        diurnal = np.sqrt(2.0) * np.cos(2.0 * np.pi * (minute - peak) / pub.LOAD_MINUTES)
        latent = weight * diurnal + _ar1(rng, pub.LOAD_MINUTES, phi)
        data[f"device_{device}"] = _rank_to_counts(latent, lo, med, hi)
    return pd.DataFrame(data)


CSV_GENERATORS: dict[str, Callable[[np.random.Generator], pd.DataFrame]] = {
    "bandwidth.csv": generate_bandwidth,
    "propagation.csv": generate_propagation,
    "compute_uc1.csv": generate_compute_uc1,
    "compute_uc2.csv": generate_compute_uc2,
    "compute_uc3.csv": generate_compute_uc3,
    "load.csv": generate_load,
}


def write_csvs(seed: int, out_dir: Path, uc3_mean_latency_s: float | None = None) -> list[Path]:
    """Write every trace CSV; each file has its own child stream so files are independent.

    Args:
        seed: the traces' seed.
        out_dir: where they go.
        uc3_mean_latency_s: UC3's one-process mean per clip (None: the shipped trace's, 4.17 s).

    Returns:
        The paths written.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    children = np.random.SeedSequence(seed).spawn(len(CSV_GENERATORS))
    written = []
    for (name, generate), child in zip(CSV_GENERATORS.items(), children, strict=True):
        rng = np.random.default_rng(child)
        frame = (generate_compute_uc3(rng, uc3_mean_latency_s) if generate is generate_compute_uc3
                 else generate(rng))
        path = out_dir / name
        frame.to_csv(path, index=False, lineterminator="\n", float_format="%.6g")
        written.append(path)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    # cli's parser and run_cli, as every command's: bad input is one line and exit 2.
    parser = ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    parser.add_argument("--no-models", action="store_true", help="write the CSVs only (no TensorFlow)")
    parser.add_argument("--report", action="store_true", help="print measured vs published statistics of --out and exit")
    parser.add_argument("--uc3-mean-latency-s", type=float, default=None,
                        help="UC3's one-process mean compute time per clip (default: README §4.4's "
                             "derivation, 4.17 s; docs/calibration.md rule 6 tried others)")
    args = parser.parse_args(argv)
    if args.report:
        # The checks live beside this script (check_traces.py), loaded by path like this one.
        spec = importlib.util.spec_from_file_location("traces_check_traces", Path(__file__).with_name("check_traces.py"))
        checks = sys.modules[spec.name] = importlib.util.module_from_spec(spec)  # for its dataclass
        spec.loader.exec_module(checks)
        return 0 if checks.print_report(args.out) else 1
    if args.uc3_mean_latency_s is not None and not args.uc3_mean_latency_s > 0:
        parser.error(f"--uc3-mean-latency-s: expected a positive number of seconds, got {args.uc3_mean_latency_s}")
    for path in write_csvs(args.seed, args.out, args.uc3_mean_latency_s):
        print(f"wrote {path} ({path.stat().st_size} bytes)")
    if not args.no_models:
        from yafs_safetail.edge.compute import train_compute_models  # imports TensorFlow

        for path in train_compute_models(args.out, args.out / "models", seed=args.seed):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
