"""What a contention run is given: :class:`ContentionConfig` and its checks, and the two inputs
it may name besides the traces and topology: an arrivals CSV (:func:`read_arrivals`) and each
user's distance conditions (:func:`user_conditions`).

``contention.world.ContentionWorld`` builds a run's world from these; every name here is also
importable from ``contention.world``. It also names what a run is scored against
(:data:`TARGETS`) and what its summary row holds (:data:`SUMMARY_COLUMNS`).

Only light modules at import (NumPy loads when an input is read): the sweep commands declare
their options with these before anything heavy loads (``tests/test_first_answer.py``).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from yafs_safetail.defaults import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY
from yafs_safetail.edge.energy import EnergyModel
from yafs_safetail.edge.failure_settings import FailureSettings
from yafs_safetail.settings.world import WORLD_OVERRIDES, WorldOverrides

if TYPE_CHECKING:
    import numpy as np

    from yafs_safetail.edge.scenario import EdgeScenario

#: Requests drawn per block (memory stays bounded however long the run).
DEFAULT_BLOCK_REQUESTS = 20_000
#: How transfers share a server's links (see ``contention.world``'s docstring).
LINK_MODELS: tuple[str, ...] = ("shared", "at-start")
#: What a policy's feedback records give as the request's target τ: ``"eq4"``, Eq. 4 (the paper);
#: ``"observed-load"``, Eq. 4 with its compute term at the servers' load seen when the request
#: was dispatched (``ContentionWorld.observed_load_target_s``; docs/deviations.md D12).
TARGETS = ("eq4", "observed-load")
#: One method's figures over a run (``contention.run.summarise``'s row), in order.
SUMMARY_COLUMNS: tuple[str, ...] = (
    "method", "n_requests", "p50_s", "p90_s", "p95_s", "p99_s", "mean_s", "mean_n_selected",
    "fallback_rate", "refused_per_request", "cancelled_per_request", "server_s_per_request",
    "success_rate", "energy_j_per_request", "share_all_lost", "share_timeout", "share_all_refused",
)


class ContentionError(ValueError):
    """A contention-world setting or input that cannot make a run (one line naming it)."""


@dataclass(frozen=True)
class ContentionConfig(WorldOverrides):
    """One contention-world run of one method (everything but the method).

    Attributes:
        use_case: 1, 2 or 3.
        n_requests: requests simulated (ignored with ``arrivals_csv``: its rows are the requests).
        seed: the run's seed.
        phase: names the random streams (``"train"`` and ``"test"`` are independent worlds).
        users: U.
        load: offered utilisation of the servers' slots by the users' requests: arrival rate ×
            mean single-copy service time ÷ total slots (see
            :meth:`~yafs_safetail.contention.world.ContentionWorld.rate_for_load`).
        rate_per_user_hz: each user's Poisson rate; when given, it sets the rate and ``load`` is
            not used.
        arrivals_csv: a CSV of ``time_s,user`` rows (user in 0..U-1) instead of Poisson streams.
        queue: FIFO waiting queue at a full server instead of refusal.
        cancel: cancel the other copies when the first reply arrives.
        background: the load trace's background tenants (False: the servers serve only the users).
        links: ``"shared"`` (processor sharing over each transfer) or ``"at-start"`` (the level
            when the transfer starts); :data:`LINK_MODELS`.
        world: the world's readings and calibrated parameters (``"calibrated-v1"``, the first
            calibration, in which docs/contention.md's figures were measured; ``"calibrated"``,
            the paper presets' learner-free fit; or ``"landed"``).
        topology: topology JSON (per-server ``IPT`` and ``capacity`` are read here).
        placement: placement JSON.
        traces_dir: the traces folder (None: the repository's).
        block_requests: requests drawn per block.
        user_conditions: each user's distance condition (1..5) per server: ``"topology"`` (the
            topology's link conditions for every user), ``"generated"`` (the topology's ±1 per
            user and server, drawn once from the seed, the same in every phase) or a JSON file
            ``{"users": [{"conditions": [c_0, ..., c_{n-1}]}, ...]}`` with one entry per user.
        failures: when servers are down and how long a user waits for a reply (beyond the
            paper; the default: no server ever fails and no time-out, the paper's world).
        energy: the servers' and the devices' power models that price every copy.
        target_latency_s, load_peak_users, target_compute, baseline_reading: the run's
            overrides of the world's
            settings, as the experiment's options of these names (``settings.world.WORLD_OVERRIDES``,
            applied by the same ``settings.world.apply_world_overrides``); None keeps the
            world's own.
    """

    use_case: int = 1
    n_requests: int = 10_000
    seed: int = 0
    phase: str = "test"
    users: int = 1
    load: float | None = 0.3
    rate_per_user_hz: float | None = None
    arrivals_csv: Path | None = None
    queue: bool = False
    cancel: bool = True
    background: bool = True
    links: str = "shared"
    world: str = "calibrated-v1"
    topology: Path = DEFAULT_TOPOLOGY
    placement: Path = DEFAULT_PLACEMENT
    traces_dir: Path | None = None
    block_requests: int = DEFAULT_BLOCK_REQUESTS
    user_conditions: str | Path = "topology"
    failures: FailureSettings = FailureSettings()
    energy: EnergyModel = EnergyModel()

    def with_world_overrides(self, settings: Mapping[str, Any]) -> ContentionConfig:
        """This configuration with the world overrides a sweep point's ``settings`` record."""
        return replace(self, **{name: settings[name] for name in WORLD_OVERRIDES if name in settings})


def check_contention_config(config: ContentionConfig) -> None:
    """The settings a run cannot start with, as a one-line :class:`ContentionError`."""
    def positive_int(name: str, value: object) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ContentionError(f"{name}: expected a positive integer, got {value!r}")

    positive_int("--users", config.users)
    positive_int("--requests", config.n_requests)
    positive_int("block_requests", config.block_requests)
    if config.links not in LINK_MODELS:
        raise ContentionError(f"--links: expected one of {', '.join(LINK_MODELS)}, got {config.links!r}")
    if config.arrivals_csv is None:
        if config.load is None and config.rate_per_user_hz is None:
            raise ContentionError("--load / --rate-per-user: give one of them")
        by_rate = config.rate_per_user_hz is not None
        value = config.rate_per_user_hz if by_rate else config.load
        if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
            name = "--rate-per-user" if by_rate else "--load"
            raise ContentionError(f"{name}: expected a positive number, got {value!r}")
    if not isinstance(config.failures, FailureSettings):
        raise ContentionError(f"failures: expected a FailureSettings, got {config.failures!r}")
    if not isinstance(config.energy, EnergyModel):
        raise ContentionError(f"energy: expected an EnergyModel, got {config.energy!r}")


def read_arrivals(path: Path, users: int) -> tuple[np.ndarray, np.ndarray]:
    """``time_s,user`` rows, checked (one-line errors), sorted by time (stable)."""
    import numpy as np  # here, not at the top: the sweep commands' options import this module

    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise ContentionError(f"{path}: file: cannot read arrivals ({exc.strerror})") from None
    if not rows or [c.strip() for c in rows[0]] != ["time_s", "user"]:
        raise ContentionError(f"{path}: header: expected the columns time_s,user")
    times, who = [], []
    for number, row in enumerate(rows[1:], start=2):
        if len(row) != 2:
            raise ContentionError(f"{path}: line {number}: expected 2 values, got {len(row)}")
        try:
            time_s, user = float(row[0]), int(row[1])
        except ValueError:
            raise ContentionError(f"{path}: line {number}: not a number and an integer: {row!r}") from None
        if not math.isfinite(time_s) or time_s < 0:
            raise ContentionError(f"{path}: line {number}: time_s must be a finite non-negative number")
        if not 0 <= user < users:
            raise ContentionError(f"{path}: line {number}: user {user} is not in 0..{users - 1} (--users {users})")
        times.append(time_s)
        who.append(user)
    if not times:
        raise ContentionError(f"{path}: rows: no arrivals")
    order = np.argsort(np.asarray(times), kind="stable")
    return np.asarray(times)[order], np.asarray(who, dtype=np.int64)[order]


def user_conditions(config: ContentionConfig, scenario: EdgeScenario, known: tuple[int, ...]) -> np.ndarray:
    """Each user's distance condition per server, shape (U, n) (see ``ContentionConfig``)."""
    import numpy as np  # here, not at the top: the sweep commands' options import this module

    from yafs_safetail.edge.sampling import phase_seed_sequence

    topology = np.asarray(scenario.server_conditions, dtype=np.int64)
    choice = config.user_conditions
    if choice == "topology":
        return np.tile(topology, (config.users, 1))
    if choice == "generated":
        rng = np.random.default_rng(phase_seed_sequence(config.seed, "users"))
        shifted = topology[None, :] + rng.integers(-1, 2, size=(config.users, topology.size))
        return np.clip(shifted, min(known), max(known))
    path = Path(choice)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ContentionError(f"{path}: file: cannot read user conditions ({exc.strerror})") from None
    except ValueError as exc:
        raise ContentionError(f"{path}: file: invalid JSON ({exc})") from None
    users = data.get("users") if isinstance(data, dict) else None
    if not isinstance(users, list) or len(users) != config.users:
        raise ContentionError(f"{path}: users: expected a list of {config.users} users (--users {config.users})")
    rows = []
    for index, user in enumerate(users):
        conditions = user.get("conditions") if isinstance(user, dict) else None
        if (not isinstance(conditions, list) or len(conditions) != topology.size
                or not all(isinstance(c, int) and not isinstance(c, bool) and c in known for c in conditions)):
            raise ContentionError(f"{path}: users[{index}].conditions: expected {topology.size} conditions "
                                  f"from {list(known)}, got {conditions!r}")
        rows.append(conditions)
    return np.asarray(rows, dtype=np.int64)
