"""Published figures the edge model and the trace generator rely on, in one place.

Every constant cites its source: ``facts`` is ``shared/spec/facts.md`` (figures from the paper
and from public follow-up material on the original SafeTail code), ``paper`` is
``shared/paper/safetail_paper.tex``. Units are SI (seconds, bytes, bits per second) unless a
name says otherwise. Values derived by this project (not published) are marked *derived* and
their derivation is in ``traces/README.md``.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Final

# 1 = YOLOv5 object detection, 2 = instance segmentation, 3 = audio noise removal (paper §V-A): in
# defaults.py, since the settings (the lowest floor) and the command line list them.
from yafs_safetail.defaults import USE_CASES as USE_CASES

MAX_PROCESSES: Final[int] = 5
"""Parallel processes measured per server, k = 1..5 (paper §V-A "Modeling Computation Latency")."""

N_EDGE_SERVERS: Final[int] = 5
"""n in Table I (facts: "n = 5 homogeneous edge servers")."""

MAX_LOAD_PER_SERVER: Final[int] = 4
"""Table I "Maximum load for each edge server" (facts line 2 of "From the paper")."""

# facts, "σ_k (k = 1..5 parallel processes)": UC1 in ms, UC2 units not stated (treated as ms,
# as facts.md says), UC3 in s. Converted to seconds here.
SIGMA_S: Final = MappingProxyType(
    {
        1: (0.00280, 0.00639, 0.00552, 0.00710, 0.00691),
        2: (0.00418, 0.0275, 0.0351, 0.0399, 0.0400),
        3: (0.0252, 0.0270, 0.0275, 0.0299, 0.0315),
    }
)
"""σ_k in seconds per use case, index k - 1 (facts, "σ_k")."""

BATCH_WALL_TIME_S: Final = MappingProxyType(
    {
        1: (133.8, 216.1, 291.8),
        2: (206.8, 295.4, 410.0),
        3: (15.5, 16.8, 18.3),
    }
)
"""Batch wall time with k = 1, 2, 3 parallel processes of one type (facts, "Slow-down")."""

CPU_PERCENT_PER_PROCESS: Final[tuple[float, ...]] = (779.0, 740.0, 531.0, 399.0, 319.0)
"""CPU % of one process when k = 1..5 run together (facts, "Slow-down"; 16 vCPUs = 1600 %)."""

MEMORY_MB_RANGE: Final[tuple[float, float]] = (829.0, 853.0)
"""Server memory in MB with k = 1 and k = 5 processes (facts, "Slow-down")."""

UC1_ONE_PROCESS_S: Final = MappingProxyType(
    {
        "count": 5660,
        "median": 0.450,
        "mean": 0.455,
        "p90": 0.514,
        "p99": 0.600,
        "min": 0.225,
        "max": 0.631,
    }
)
"""YOLOv5 latency with one process, COCO val2017 (facts, "Compute, UC1")."""

UC1_RESOLUTIONS: Final = MappingProxyType(
    {
        "distinct": 19,
        "most_common_hxw": ((480, 640), (448, 640), (640, 480), (640, 448), (640, 640)),
        "min_pixels": 184_320,
        "median_pixels": 307_200,
        "max_pixels": 409_600,
    }
)
"""Image resolutions (height x width) seen by the UC1 service (facts, "Compute, UC1")."""

COCO_VAL2017_IMAGES: Final[int] = 5000
COCO_VAL2017_TOTAL_BYTES: Final[float] = 788e6
"""COCO val2017 size (facts, "Sizes"): about 160 KB per image on average."""

AUDIO_BYTES_PER_S: Final[int] = 32_000
"""16-bit PCM at 16 kHz (facts, "Sizes")."""

WAV_HEADER_BYTES: Final[int] = 44
"""Canonical RIFF/WAVE header size; added to every audio clip's PCM payload."""

UNCONTENDED_BANDWIDTH_BPS: Final[float] = 20e6
"""Bandwidth of an uncontended WiFi link; the original code's constant (facts, "Bandwidth")."""

MAX_CONTENTION_LEVEL: Final[int] = 4
"""Extra contending WiFi devices measured: 0..4 Raspberry Pis (paper §V-A)."""

PROPAGATION_RTT_S: Final = MappingProxyType(
    {
        1: {"min": 0.034, "p10": 0.043, "median": 0.051, "mean": 0.060, "p90": 0.086, "p99": 0.174, "max": 0.440},
        2: {"min": 0.037, "p10": 0.072, "median": 0.126, "mean": 0.150, "p90": 0.242, "p99": 0.588, "max": 0.956},
        3: {"min": 0.038, "p10": 0.182, "median": 0.513, "mean": 0.550, "p90": 0.998, "p99": 1.312, "max": 1.503},
        4: {"min": 0.073, "p10": 0.244, "median": 0.676, "mean": 0.688, "p90": 1.172, "p99": 1.453, "max": 1.720},
        5: {"min": 0.260, "p10": 0.521, "median": 0.712, "mean": 0.732, "p90": 0.958, "p99": 1.301, "max": 1.543},
    }
)
"""Ping RTT statistics per signal condition 1 (near) .. 5 (far) (facts, "Propagation latency")."""

PROPAGATION_SAMPLES_PER_CONDITION: Final[int] = 500
"""Ping packets per condition (paper §V-A "Modeling Propagation Latency")."""

LOAD_MINUTES: Final[int] = 1440
LOAD_DEVICE_MIN_MEDIAN_MAX: Final[tuple[tuple[int, int, int], ...]] = (
    (82, 124, 166),
    (102, 500, 607),
    (5, 19, 36),
    (41, 122, 171),
    (0, 1, 4),
    (37, 57, 89),
    (33, 50, 73),
    (73, 109, 175),
    (8, 94, 148),
    (0, 3, 8),
)
"""Active users per edge device over one day, min / median / max (facts, "Load")."""

LOAD_LAG1_AUTOCORR_RANGE: Final[tuple[float, float]] = (0.90, 0.998)
"""Lag-1 autocorrelation range over the devices (facts, "Load")."""

LOAD_DAY_NIGHT_LEVELS: Final = MappingProxyType({"night_minute": 180, "night": 1.3, "day_minute": 900, "day": 4.8})
"""One device's mean level at 03:00 and 15:00 after min-max scaling into 1..5 (facts, "Load")."""


def slowdown_factors(use_case: int) -> tuple[float, ...]:
    """Per-request slow-down s_k = T_k / T_1 for k = 1..5 (*derived*).

    k = 1..3 are the published batch wall-time ratios. Beyond k = 3 the 16 vCPUs are saturated
    (k x CPU% per process is ~1600 % from k = 3 on), so the extra slow-down follows the loss of
    CPU share per process, with the elasticity measured between k = 2 and 3, where saturation
    begins: s_k = s_3 * (1 + e * (cpu_3 / cpu_k - 1)), e = (s_3 / s_2 - 1) / (cpu_2 / cpu_3 - 1).

    Args:
        use_case: 1, 2 or 3.

    Returns:
        (s_1, ..., s_5) with s_1 = 1.

    Raises:
        ValueError: unknown use case.
    """
    if use_case not in BATCH_WALL_TIME_S:
        raise ValueError(f"use_case: {use_case!r} is not one of {USE_CASES}")
    wall = BATCH_WALL_TIME_S[use_case]
    measured = [t / wall[0] for t in wall]
    cpu = CPU_PERCENT_PER_PROCESS
    elasticity = (measured[2] / measured[1] - 1.0) / (cpu[1] / cpu[2] - 1.0)
    extrapolated = [measured[2] * (1.0 + elasticity * (cpu[2] / cpu[k] - 1.0)) for k in (3, 4)]
    return tuple(measured + extrapolated)
