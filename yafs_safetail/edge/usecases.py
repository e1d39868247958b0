"""The paper's three use cases, in one place.

For each: the compute-trace file whose rows are the requests (a request copies a row's input
size and its Γ), the Γ columns the compute model uses (the number of parallel processes k
is a server property and is passed separately), how the actual and the *estimated* output
sizes follow from the input, ν (the parallelism whose median compute time enters the target
latency τ, Eq. 4) and the latency of the on-device fallback (assumption iv) used when every
chosen server refuses.

How ν and the fallback latencies were derived is in ``docs/edge_model.md``; the tests check
them against the shipped traces.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from yafs_safetail.edge import published

KILOBYTE = 1024.0


@dataclass(frozen=True)
class UseCase:
    """One service s_j of the paper.

    Attributes:
        number: 1, 2 or 3.
        name: short name (used in file names and tables).
        description: what the service does.
        compute_trace: the compute-trace CSV (in the traces folder) the requests come from.
        input_bytes_column: the column holding Size(I).
        gamma_columns: the Γ columns (besides the number of processes) the compute model reads.
        nu: ν of Eq. 4.
        fallback_latency_s: latency of the lightweight on-device version (assumption iv): the
            service's latency tolerance bound, at least the worst-case edge latency under the
            shipped traces, so falling back is never faster than an edge reply.
        output_bytes_fn: actual Size(O) from the input sizes and the request stream's
            generator (vectorised).
        estimate_bytes_fn: eSize(O) from the input sizes (vectorised, deterministic).
        output_bound_fn: an upper bound of Size(O) given the input size.
        typical_input_bytes: a typical Size(I) (COCO images average about 160 KB; a 5 s clip
            of 16-bit 16 kHz audio is 160 KB), e.g. to bring the state's sizes to O(1).
        typical_output_bytes: a typical eSize(O) (a few KB of detections; masks at about 0.4 of
            the image; the denoised clip at the input's size).
    """

    number: int
    name: str
    description: str
    compute_trace: str
    input_bytes_column: str
    gamma_columns: tuple[str, ...]
    nu: int
    fallback_latency_s: float
    output_bytes_fn: Callable[[np.ndarray, np.random.Generator], np.ndarray]
    estimate_bytes_fn: Callable[[np.ndarray], np.ndarray]
    output_bound_fn: Callable[[float], float]
    typical_input_bytes: float
    typical_output_bytes: float

    def draw_output_bytes(self, input_bytes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Actual output sizes of requests with these input sizes."""
        return self.output_bytes_fn(np.asarray(input_bytes, dtype=float), rng)

    def estimate_output_bytes(self, input_bytes: np.ndarray) -> np.ndarray:
        """eSize(O): what the user can predict before the reply arrives."""
        return self.estimate_bytes_fn(np.asarray(input_bytes, dtype=float))

    def output_bytes_bound(self, input_bytes: float) -> float:
        """Largest possible Size(O) for an input of ``input_bytes``."""
        return float(self.output_bound_fn(float(input_bytes)))


# UC1: a YOLOv5 reply is a list of detections (class, score, box) serialised as JSON: a few
# KB, independent of the image. Estimate: the middle of the range.
DETECTIONS_BYTES_RANGE = (1.0 * KILOBYTE, 6.0 * KILOBYTE)
DETECTIONS_ESTIMATE_BYTES = 3.5 * KILOBYTE
# UC2: the reply carries per-instance masks (compressed), growing with the image: a fraction
# of the input. Estimate: the mean fraction.
MASK_FRACTION_RANGE = (0.2, 0.6)
MASK_ESTIMATE_FRACTION = 0.4


def _detections_bytes(input_bytes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(*DETECTIONS_BYTES_RANGE, size=input_bytes.shape)


def _masks_bytes(input_bytes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return input_bytes * rng.uniform(*MASK_FRACTION_RANGE, size=input_bytes.shape)


def _same_as_input(input_bytes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return input_bytes.copy()


OBJECT_DETECTION = UseCase(
    number=1,
    name="object_detection",
    description="YOLOv5 single-shot object detection on COCO images",
    compute_trace="compute_uc1.csv",
    input_bytes_column="file_bytes",
    gamma_columns=(),
    nu=4,
    fallback_latency_s=15.0,
    output_bytes_fn=_detections_bytes,
    estimate_bytes_fn=lambda size: np.full_like(size, DETECTIONS_ESTIMATE_BYTES),
    output_bound_fn=lambda size: DETECTIONS_BYTES_RANGE[1],
    typical_input_bytes=160e3,
    typical_output_bytes=4e3,
)

INSTANCE_SEGMENTATION = UseCase(
    number=2,
    name="instance_segmentation",
    description="instance segmentation on COCO images",
    compute_trace="compute_uc2.csv",
    input_bytes_column="file_bytes",
    gamma_columns=("file_bytes",),
    nu=3,
    fallback_latency_s=20.0,
    output_bytes_fn=_masks_bytes,
    estimate_bytes_fn=lambda size: MASK_ESTIMATE_FRACTION * size,
    output_bound_fn=lambda size: MASK_FRACTION_RANGE[1] * size,
    typical_input_bytes=160e3,
    typical_output_bytes=64e3,
)

NOISE_REMOVAL = UseCase(
    number=3,
    name="noise_removal",
    description="noise removal from WAV audio clips (the denoised clip has the input's size)",
    compute_trace="compute_uc3.csv",
    input_bytes_column="file_bytes",
    gamma_columns=("file_bytes", "duration_s"),
    nu=2,
    fallback_latency_s=24.0,
    output_bytes_fn=_same_as_input,
    estimate_bytes_fn=lambda size: size.copy(),
    output_bound_fn=lambda size: size,
    typical_input_bytes=160e3,
    typical_output_bytes=160e3,
)

#: The use cases, keyed by number: the numbers are ``published.USE_CASES``, the one list of them.
USE_CASES: dict[int, UseCase] = {uc.number: uc for uc in (OBJECT_DETECTION, INSTANCE_SEGMENTATION, NOISE_REMOVAL)}
assert tuple(USE_CASES) == published.USE_CASES


class UnknownUseCaseError(ValueError):
    """A use case number that is not 1, 2 or 3."""


def get_use_case(number: int) -> UseCase:
    """The use case ``number`` (1, 2 or 3).

    Raises:
        UnknownUseCaseError: any other value.
    """
    try:
        return USE_CASES[int(number)]
    except (KeyError, TypeError, ValueError):
        raise UnknownUseCaseError(
            f"use case: {number!r} is not one of {sorted(USE_CASES)}"
        ) from None


def knee_processes(median_by_k_s: np.ndarray) -> int:
    """ν from a compute trace: the knee of the median compute time versus k.

    The knee is the k farthest *below* the straight line joining k = 1 and the largest k, on
    axes scaled to [0, 1] (the Kneedle definition for an increasing convex curve): up to it,
    extra parallel instances cost less than their average; beyond it, more. Ties go to the
    smaller k; a curve never below the line (no knee) gives 1.

    Args:
        median_by_k_s: median compute latency for k = 1..K.

    Returns:
        ν in 1..K.
    """
    medians = np.asarray(median_by_k_s, dtype=float)
    span = medians[-1] - medians[0]
    if medians.size < 3 or span <= 0:
        return 1
    x = np.linspace(0.0, 1.0, medians.size)
    y = (medians - medians[0]) / span
    below = x - y
    best = int(np.argmax(below))
    return best + 1 if below[best] > 0 else 1
