"""The paper's latency formulas as pure, vectorised functions.

Eq. 1 gives the latency of one copy of a request served by edge server *i*; Eq. 4 gives the
target latency τ the reward compares against. Every function accepts floats or NumPy arrays
(broadcasting), so the world can evaluate whole (step, server) tables at once.

Units: sizes in bytes, bandwidths in bits per second, times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BITS_PER_BYTE = 8.0


def transfer_s(size_bytes, bandwidth_bps):
    """Time to push ``size_bytes`` through a link of ``bandwidth_bps``."""
    return np.multiply(size_bytes, BITS_PER_BYTE) / bandwidth_bps


def input_bottleneck_bps(server_downlink_bps, user_uplink_bps):
    """min(λ^d_i, Λ^u): the input leaves the user's uplink and enters the server's downlink."""
    return np.minimum(server_downlink_bps, user_uplink_bps)


def output_bottleneck_bps(server_uplink_bps, user_downlink_bps):
    """min(λ^u_i, Λ^d): the output leaves the server's uplink and enters the user's downlink."""
    return np.minimum(server_uplink_bps, user_downlink_bps)


@dataclass(frozen=True, slots=True)
class CopyLatency:
    """One copy's Eq. 1 latency split into its terms.

    Eq. 1 charges the same transfer time twice per direction (once "uploading", once
    "downloading") and the propagation ρ_i twice (input and output), so each field is the sum
    of the input-side and output-side terms.

    Attributes:
        input_upload_s: Size(I)/min(λ^d_i, Λ^u), the input's uploading term.
        input_download_s: the input's downloading term (equal to the uploading term).
        input_propagation_s: ρ_i on the way to the server.
        compute_s: C(e_i, s_j).
        output_upload_s: Size(O)/min(λ^u_i, Λ^d), the output's uploading term.
        output_propagation_s: ρ_i on the way back.
        output_download_s: the output's downloading term (equal to its uploading term).
    """

    input_upload_s: float
    input_download_s: float
    input_propagation_s: float
    compute_s: float
    output_upload_s: float
    output_propagation_s: float
    output_download_s: float

    @property
    def upload_s(self) -> float:
        return self.input_upload_s + self.output_upload_s

    @property
    def download_s(self) -> float:
        return self.input_download_s + self.output_download_s

    @property
    def propagation_s(self) -> float:
        return self.input_propagation_s + self.output_propagation_s

    @property
    def total_s(self) -> float:
        """L_i of Eq. 1."""
        return (
            self.input_upload_s
            + self.input_propagation_s
            + self.input_download_s
            + self.compute_s
            + self.output_upload_s
            + self.output_propagation_s
            + self.output_download_s
        )


def copy_latency(
    input_bytes: float,
    output_bytes: float,
    server_uplink_bps: float,
    server_downlink_bps: float,
    user_uplink_bps: float,
    user_downlink_bps: float,
    propagation_s: float,
    compute_s: float,
) -> CopyLatency:
    """Eq. 1 for one copy, term by term.

    Args:
        input_bytes: Size(I_j).
        output_bytes: Size(O_j), the actual output size.
        server_uplink_bps: λ^u_i.
        server_downlink_bps: λ^d_i.
        user_uplink_bps: Λ^u.
        user_downlink_bps: Λ^d.
        propagation_s: ρ_i(L), charged once on the way in and once on the way out.
        compute_s: C(e_i, s_j).

    Returns:
        The copy's latency terms.
    """
    input_s = float(transfer_s(input_bytes, input_bottleneck_bps(server_downlink_bps, user_uplink_bps)))
    output_s = float(
        transfer_s(output_bytes, output_bottleneck_bps(server_uplink_bps, user_downlink_bps))
    )
    return CopyLatency(
        input_upload_s=input_s,
        input_download_s=input_s,
        input_propagation_s=float(propagation_s),
        compute_s=float(compute_s),
        output_upload_s=output_s,
        output_propagation_s=float(propagation_s),
        output_download_s=output_s,
    )


def copy_latency_s(
    input_bytes,
    output_bytes,
    server_uplink_bps,
    server_downlink_bps,
    user_uplink_bps,
    user_downlink_bps,
    propagation_s,
    compute_s,
):
    """Eq. 1's total L_i, vectorised over any broadcastable arrays (same arguments as
    :func:`copy_latency`)."""
    input_s = transfer_s(input_bytes, input_bottleneck_bps(server_downlink_bps, user_uplink_bps))
    output_s = transfer_s(output_bytes, output_bottleneck_bps(server_uplink_bps, user_downlink_bps))
    return 2.0 * input_s + 2.0 * np.asarray(propagation_s) + compute_s + 2.0 * output_s


def target_latency_s(
    input_bytes,
    est_output_bytes,
    user_uplink_bps,
    user_downlink_bps,
    server_median_propagation_s,
    median_compute_s,
):
    """Eq. 4: the target latency τ(ω^t).

    Only the user's bandwidths enter the transfer terms (the paper argues the user's link is
    the bottleneck), the propagation is the median over servers of each server's median
    propagation ρ^μ_i, and the compute term is the median compute time at ν parallel
    instances.

    Args:
        input_bytes: Size(I_j).
        est_output_bytes: eSize(O_j), the estimated output size (the actual one is unknown
            when τ is computed).
        user_uplink_bps: Λ^u.
        user_downlink_bps: Λ^d.
        server_median_propagation_s: ρ^μ_i for every server; the last axis is the server axis.
        median_compute_s: C(s_j), the median compute time at ν instances.

    Returns:
        τ in seconds (an array when the inputs are arrays).
    """
    rho_median_s = np.median(np.asarray(server_median_propagation_s, dtype=float), axis=-1)
    return (
        2.0 * transfer_s(input_bytes, user_uplink_bps)
        + 2.0 * rho_median_s
        + median_compute_s
        + 2.0 * transfer_s(est_output_bytes, user_downlink_bps)
    )
