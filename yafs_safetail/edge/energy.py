"""What a copy costs in energy: the servers' power model and the user device's radio (beyond the
paper, which prices a copy only by its "access rate").

Server: linear in its active processes, ``P(n) = idle_w + n * per_process_w`` with
``per_process_w = (max_w - idle_w) / max_processes``: the package draws ``max_w`` at the load
limit (EdgeSimPy's linear model with utilisation = n / limit). A copy is charged its marginal
power over the time it computed (all of its compute time, or until it was cancelled or its
server failed), so a server's copies add up to its dynamic energy exactly; the idle part is
the server's alone and never a request's.

Radio (the user's device): ``P = alpha_w_per_bps * rate + beta_w`` while a transfer is on the
air, uplink and downlink with their own slopes (Huang et al., MobiSys 2012, WiFi), so a
transfer of ``b`` bits at rate ``r`` costs ``alpha * b + beta * b / r``.

Sources (docs/failures_energy.md has the table): every use case ran on the paper's one server machine
(an Intel Core i7-11700, paper §V-A), so the three use cases share the server model and differ
in energy through their compute times and payload sizes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from yafs_safetail.edge.published import MAX_LOAD_PER_SERVER

#: Intel's "processor base power" of the Core i7-11700 (Intel ARK), the paper's server CPU:
#: what its package sustains under full load.
I7_11700_BASE_POWER_W = 65.0
#: Package power with no request running: our assumption, not from a source we could check
#: (Rocket Lake desktops idle at a few watts to a few tens of watts depending on the board).
#: It sets ``per_process_w`` with the base power; a user sets both with the run's options.
ASSUMED_IDLE_POWER_W = 10.0
#: WiFi radio power model of Huang et al., "A Close Examination of Performance and Power
#: Characteristics of 4G LTE Networks", MobiSys 2012: P = alpha_u * uplink Mbps + alpha_d *
#: downlink Mbps + beta, in mW. Here per bit/s and in watts.
WIFI_ALPHA_UP_W_PER_BPS = 283.17e-3 / 1e6
WIFI_ALPHA_DOWN_W_PER_BPS = 137.01e-3 / 1e6
WIFI_BETA_W = 132.86e-3


@dataclass(frozen=True)
class ServerPowerModel:
    """A server's power: idle, plus the same marginal power for each active process.

    Attributes:
        idle_w: power with no process running.
        max_w: power at ``max_processes`` active processes.
        max_processes: the load at which the server draws ``max_w``.
    """

    idle_w: float = ASSUMED_IDLE_POWER_W
    max_w: float = I7_11700_BASE_POWER_W
    max_processes: int = MAX_LOAD_PER_SERVER

    def __post_init__(self) -> None:
        for name in ("idle_w", "max_w"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be a power >= 0 W, got {value!r}")
        if self.max_w < self.idle_w:
            raise ValueError(f"max_w: must be at least idle_w ({self.idle_w} W), got {self.max_w!r}")
        if self.max_processes < 1:
            raise ValueError(f"max_processes: must be >= 1, got {self.max_processes!r}")

    @property
    def per_process_w(self) -> float:
        """The marginal power of one active process."""
        return (self.max_w - self.idle_w) / self.max_processes

    def power_w(self, active_processes: float) -> float:
        """The server's power with this many processes running."""
        return self.idle_w + active_processes * self.per_process_w

    def copy_energy_j(self, compute_s: float) -> float:
        """What a copy that computed for ``compute_s`` seconds cost its server."""
        return self.per_process_w * compute_s


@dataclass(frozen=True)
class RadioPowerModel:
    """The user device's radio while it sends or receives (linear in throughput).

    Attributes:
        alpha_up_w_per_bps: uplink power per bit/s of throughput.
        alpha_down_w_per_bps: downlink power per bit/s of throughput.
        beta_w: power of the radio being active at all.
    """

    alpha_up_w_per_bps: float = WIFI_ALPHA_UP_W_PER_BPS
    alpha_down_w_per_bps: float = WIFI_ALPHA_DOWN_W_PER_BPS
    beta_w: float = WIFI_BETA_W

    def __post_init__(self) -> None:
        for name in ("alpha_up_w_per_bps", "alpha_down_w_per_bps", "beta_w"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be >= 0, got {value!r}")

    def upload_energy_j(self, size_bytes: float, transfer_s: float) -> float:
        """Sending ``size_bytes`` over ``transfer_s`` seconds: power at that rate x the time."""
        return self.alpha_up_w_per_bps * 8.0 * size_bytes + self.beta_w * transfer_s

    def download_energy_j(self, size_bytes: float, transfer_s: float) -> float:
        """Receiving ``size_bytes`` over ``transfer_s`` seconds."""
        return self.alpha_down_w_per_bps * 8.0 * size_bytes + self.beta_w * transfer_s


@dataclass(frozen=True)
class EnergyModel:
    """The servers' and the user device's power models of a run."""

    server: ServerPowerModel = ServerPowerModel()
    radio: RadioPowerModel = RadioPowerModel()
