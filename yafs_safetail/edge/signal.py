"""A link's condition (1..5) from the distance between the user and a server.

The paper measured its propagation pools at five signal conditions, near (1) to far (5)
(facts.md), without saying which distances they were. The rule here is stated, not fitted:

1. **Path loss**, the log-distance model (Rappaport, *Wireless Communications*, 2nd ed.,
   §4.9.1): PL(d) = PL(d₀) + 10·n·log₁₀(d / d₀), with d₀ = 1 m and PL(d₀) the free-space loss
   at 1 m for 2.4 GHz WiFi, 20·log₁₀(4π·d₀·f / c) ≈ 40.05 dB; the exponent n = 3, inside the
   2.7–3.5 the same table gives for urban areas and between its in-building line-of-sight
   (1.6–1.8) and obstructed (4–6) values.
2. **Received power** RSSI = P_tx − PL(d), with P_tx = 20 dBm (100 mW, the EU limit for
   2.4 GHz WiFi).
3. **Condition** by the received-power bands WiFi tools commonly report: above −50 dBm
   excellent (1), −50 to −60 good (2), −60 to −70 fair (3), −70 to −80 weak (4), at or below
   −80 poor (5); a band's upper edge belongs to the better condition.

With these numbers the conditions change at about 10, 21, 46 and 100 m
(:meth:`SignalRule.distance_edges_m`). A user at the server's position (d < d₀) is at d₀:
the model is not meant for less than a metre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SPEED_OF_LIGHT_MPS = 299_792_458.0
WIFI_FREQUENCY_HZ = 2.4e9
CONDITIONS = (1, 2, 3, 4, 5)


@dataclass(frozen=True)
class SignalRule:
    """Distance to condition: log-distance path loss and received-power bands.

    Attributes:
        tx_power_dbm: P_tx.
        frequency_hz: the carrier, for the free-space loss at ``reference_m``.
        path_loss_exponent: n.
        reference_m: d₀.
        band_edges_dbm: the received power at which condition k + 1 begins, best first
            (four edges for five conditions, decreasing).
    """

    tx_power_dbm: float = 20.0
    frequency_hz: float = WIFI_FREQUENCY_HZ
    path_loss_exponent: float = 3.0
    reference_m: float = 1.0
    band_edges_dbm: tuple[float, ...] = (-50.0, -60.0, -70.0, -80.0)

    def __post_init__(self) -> None:
        edges = self.band_edges_dbm
        if len(edges) != len(CONDITIONS) - 1 or any(a <= b for a, b in zip(edges, edges[1:], strict=False)):
            raise ValueError(f"band_edges_dbm: expected {len(CONDITIONS) - 1} decreasing values, got {edges!r}")
        if not (self.path_loss_exponent > 0 and self.reference_m > 0 and self.frequency_hz > 0):
            raise ValueError("path_loss_exponent, reference_m and frequency_hz must be positive")

    @property
    def reference_loss_db(self) -> float:
        """PL(d₀): the free-space loss at d₀."""
        return 20.0 * math.log10(4.0 * math.pi * self.reference_m * self.frequency_hz / SPEED_OF_LIGHT_MPS)

    def received_dbm(self, distance_m: np.ndarray | float) -> np.ndarray:
        """RSSI at ``distance_m`` (clamped below at d₀)."""
        d = np.maximum(np.asarray(distance_m, dtype=float), self.reference_m)
        return np.asarray(self.tx_power_dbm - self.reference_loss_db
                          - 10.0 * self.path_loss_exponent * np.log10(d / self.reference_m))

    def condition(self, distance_m: np.ndarray | float) -> np.ndarray:
        """The condition (1..5, int64) at each distance: 1 + the number of band edges above
        the received power (an edge met exactly keeps the better condition)."""
        rssi = self.received_dbm(distance_m)
        edges = np.asarray(self.band_edges_dbm)
        return np.asarray(1 + (rssi[..., None] < edges).sum(axis=-1), dtype=np.int64)

    def distance_edges_m(self) -> tuple[float, ...]:
        """The distances at which the condition changes (increasing)."""
        budget = self.tx_power_dbm - self.reference_loss_db
        return tuple(self.reference_m * 10.0 ** ((budget - edge) / (10.0 * self.path_loss_exponent))
                     for edge in self.band_edges_dbm)


def distances_m(user_xy_m: np.ndarray, servers_xy_m: np.ndarray) -> np.ndarray:
    """Distance from each user position (shape (k, 2)) to each server (shape (n, 2)): (k, n)."""
    user = np.asarray(user_xy_m, dtype=float).reshape(-1, 1, 2)
    servers = np.asarray(servers_xy_m, dtype=float).reshape(1, -1, 2)
    return np.asarray(np.hypot(user[..., 0] - servers[..., 0], user[..., 1] - servers[..., 1]))


#: The rule a run uses (docs/mobility.md).
DEFAULT_SIGNAL_RULE = SignalRule()
