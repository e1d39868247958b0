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

import argparse
import csv
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from yafs_safetail.edge.energy import EnergyModel
from yafs_safetail.edge.failure_settings import FailureSettings
from yafs_safetail.settings.checks import BOOLEAN, POSITIVE_INTEGER, POSITIVE_NUMBER, Check, one_of
from yafs_safetail.settings.declare import (
    SettingError,
    check_config,
    field_of,
    same_as,
    setting,
    setting_of,
)
from yafs_safetail.settings.experiment import Mobility, Task, WorldInputs
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


class ContentionError(SettingError):
    """A contention-world setting or input that cannot make a run (one line naming it)."""


def _servers(text: str) -> bool:
    """``--servers``: ``queue`` (True) or ``refuse`` (False)."""
    if text not in ("queue", "refuse"):
        raise argparse.ArgumentTypeError(f"expected queue or refuse, got {text!r}")
    return text == "queue"


#: What a full server does with a copy, read as ``queue``/``refuse`` on the command line.
SERVERS = Check("true (queue) or false (refuse)", lambda v: isinstance(v, bool), _servers)
#: Each user's distance conditions: a word or a file (``~`` expanded, as in every path option).
USER_CONDITIONS = Check("topology, generated or a JSON file", lambda v: isinstance(v, str | Path) and bool(str(v)),
                        os.path.expanduser)
FAILURES = Check("a FailureSettings", lambda v: isinstance(v, FailureSettings))
ENERGY = Check("an EnergyModel", lambda v: isinstance(v, EnergyModel))


@dataclass(frozen=True)
class ContentionConfig(WorldOverrides):
    """One contention-world run of one method (everything but the method).

    Every field is declared once, here or (the same setting as the experiment's) with
    ``settings.declare.same_as``; the sweep commands' world options, the checks
    (:func:`check_contention_config`) and ``ContentionEnv``'s keywords derive from them. The
    world's overrides (``target_latency_s``, ``load_peak_users``...) are inherited from
    ``settings.world.WorldOverrides`` and applied by ``settings.world.apply_world_overrides``,
    as the experiment's are; None keeps the world's own.
    """

    use_case: int = same_as(Task, "use_case")
    n_requests: int = setting(10_000, "requests simulated (ignored with arrivals_csv: its rows are the requests)",
                              check=POSITIVE_INTEGER, flag="")
    seed: int = same_as(Task, "seed")
    phase: str = setting("test", "names the random streams ('train' and 'test' are independent worlds)",
                         flag="")
    users: int = setting(1, "users U", check=POSITIVE_INTEGER)
    load: float | None = setting(
        0.3, "offered utilisation of the servers' slots by the users' requests: arrival rate × mean "
        "single-copy service time ÷ total slots (ContentionWorld.rate_for_load)", check=POSITIVE_NUMBER,
        optional=True, flag="")
    rate_per_user_hz: float | None = setting(
        None, "each user's Poisson rate; when given, it sets the rate and load is not used",
        check=POSITIVE_NUMBER, optional=True, flag="")
    arrivals_csv: Path | None = setting(
        None, "a CSV of time_s,user rows (user in 0..U-1) instead of Poisson streams", optional=True, flag="")
    queue: bool = setting(False, "what a full server does with a copy: queue (FIFO; the sweeps' default) or refuse (the "
                          "paper; a ContentionConfig's default)",
                          check=SERVERS, flag="--servers", metavar="{queue,refuse}")
    cancel: bool = setting(True, "let the other copies run to the end (default: cancelled at the first reply)",
                           check=BOOLEAN, flag="--no-cancel", action="store_false")
    background: bool = setting(True, "add the load trace's background tenants on top of the users' load",
                               check=BOOLEAN, flag="--background", action="store_true")
    links: str = setting(
        "shared", "transfers share each server's links over their duration (shared) or take the bandwidth "
        "of the level when they start (at-start, the single-user reading)", check=one_of(LINK_MODELS))
    world: str = setting(
        "calibrated-v1", "the world's readings and calibrated parameters: calibrated-v1 (the first calibration, "
        "in which docs/contention.md's figures were measured), calibrated (the paper presets' learner-free "
        "fit) or landed", flag="")
    topology: Path = same_as(WorldInputs, "topology")
    placement: Path = same_as(WorldInputs, "placement",
                              help="YAFS placement JSON (default placements/paper_5servers.json)")
    traces_dir: Path | None = same_as(WorldInputs, "traces_dir", default=None, optional=True)
    block_requests: int = setting(DEFAULT_BLOCK_REQUESTS, "requests drawn per block (memory stays bounded "
                                  "however long the run)", check=POSITIVE_INTEGER, flag="")
    user_conditions: str | Path = setting(
        "topology", "each user's distance condition per server: topology (the topology's link conditions for "
        "every user), generated (the topology's ±1 per user and server, drawn once from the seed) or a JSON "
        "file {\"users\": [{\"conditions\": [c_0, ...]}, ...]} (the contention world in the documentation)",
        check=USER_CONDITIONS)
    failures: FailureSettings = setting(
        FailureSettings(), "when servers are down and how long a user waits for a reply (beyond the paper; "
        "the default: no server ever fails and no time-out, the paper's world)", check=FAILURES, flag="")
    energy: EnergyModel = setting(EnergyModel(), "the servers' and the devices' power models that price every copy",
                                  check=ENERGY, flag="")
    # How the users move: the experiment's settings (docs/mobility.md), last so that every
    # earlier field keeps its place.
    mobility: str = same_as(
        Mobility, "mobility", help="how the users move, each on its own: off, random-waypoint (each user its own "
        "route from the topology's user position) or route (--route: every user the same route); on the move "
        "each link's condition follows the user's distance to its server, so the topology must place every "
        "edge server (e.g. topologies/campus_5servers.json)")
    route: Path | None = same_as(Mobility, "route")
    speed_mps: tuple[float, float] = same_as(Mobility, "speed_mps")
    pause_s: float = same_as(Mobility, "pause_s")

    #: What check_config raises for a bad field.
    setting_error: ClassVar[type[ValueError]] = ContentionError

    def with_world_overrides(self, settings: Mapping[str, Any]) -> ContentionConfig:
        """This configuration with the world overrides a sweep point's ``settings`` record."""
        return replace(self, **{name: settings[name] for name in WORLD_OVERRIDES if name in settings})

    def mobility_settings(self) -> dict[str, Any]:
        """How the users move, as a sweep point's settings record it (JSON values, the route's
        path absolute); nothing with mobility off, so the run id of a point whose users stay put
        is what it was before users could move."""
        if self.mobility == "off":
            return {}
        return {"mobility": self.mobility, "route": None if self.route is None else str(Path(self.route).resolve()),
                "speed_mps": [float(v) for v in self.speed_mps], "pause_s": float(self.pause_s)}

    def with_mobility(self, settings: Mapping[str, Any]) -> ContentionConfig:
        """This configuration with how the users move, as :meth:`mobility_settings` records it
        (absent: they stay put)."""
        if settings.get("mobility", "off") == "off":
            return self
        route = settings["route"]
        slowest, fastest = (float(v) for v in settings["speed_mps"])
        return replace(self, mobility=settings["mobility"], route=None if route is None else Path(route),
                       speed_mps=(slowest, fastest), pause_s=float(settings["pause_s"]))


def check_contention_config(config: ContentionConfig, style: str = "option") -> None:
    """The settings a run cannot start with, as a one-line :class:`ContentionError`: each field
    against its declared check (named as its option, or with ``style="field"`` as the field),
    then what only the fields together say."""
    check_config(config, style)
    if config.arrivals_csv is None and config.load is None and config.rate_per_user_hz is None:
        raise ContentionError(f"{setting_of(field_of(ContentionConfig, 'load')).label('load', style)} / "
                              f"{setting_of(field_of(ContentionConfig, 'rate_per_user_hz')).label('rate_per_user_hz', style)}"
                              ": give one of them")
    if config.mobility != "off" and config.user_conditions != "topology":
        raise ContentionError(f"{setting_of(field_of(ContentionConfig, 'user_conditions')).label('user_conditions', style)}"
                              f" {config.user_conditions}: only with "
                              f"{setting_of(field_of(ContentionConfig, 'mobility')).label('mobility', style)} off "
                              "(a user who moves has each link's condition from its distance)")


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
