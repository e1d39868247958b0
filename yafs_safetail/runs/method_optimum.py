"""The method's own optimum: what SafeTail's training target can reach in this world (issue 48).

Under §III's target vector SafeTail learns, for each state, the subset that most often earns an
Eq. 5 reward of exactly 0: one server that meets τ, or all n when none would
(``investigations/eq5_policies.py``, docs/deviations.md D18). This module builds that policy
without a learner, **most zeros**, and measures it on the very requests a run's test phase
sees. SafeTail's share of zero rewards, its access rate and the paper's claims about how many
servers it uses are then judged against what its own target can reach here (decision 2 of
issue 48); a claim this policy misses is "not reachable by the method here".

The flow, top to bottom:

1. :func:`request_table`: for each request of a world, the Eq. 5 reward of every one of the
   2^n - 1 subsets, read from the world's per-copy table (:func:`subset_latencies_s`,
   :func:`eq5_rewards`). One request a minute, so every copy has ended before the next request;
   the fastest chosen copy answers, or the on-device fallback when every chosen server refuses.
2. :func:`fit_most_zeros`: on the world-calibration seeds (``seed_sets.json``), each seed's test
   world (:data:`FIT_STEPS` requests, as ``eq5_policies.py``), the subset that earned exactly 0
   most often, per key.
3. :func:`apply_most_zeros`: that policy on the test worlds of the given seeds, drawn as a run
   draws them (``WorldRecipe.make_world``), so the requests are those of the run's
   ``requests.csv`` test phase (:func:`optimum_for_runs` checks it against every run: the same
   τ and, for SafeTail's own choices, the same rewards). Its share of zero rewards, servers per
   request, access rate (servers / n), β-window means and the server claims it makes hold.
4. :func:`safetail_side` reads SafeTail's share of zero rewards and access rate from a run's
   ``requests.csv``; :func:`compare` sets both side by side with issue 48's goals.

The policy itself, its key and its fit are in ``runs.most_zeros``.

Learner-free: no TensorFlow; a use case's fit takes a few seconds.
"""

from __future__ import annotations

import dataclasses
import logging
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.edge.calibration import seed_set
from yafs_safetail.methods.registry import SAFETAIL
from yafs_safetail.methods.safetail.spaces import action_of, membership_matrix
from yafs_safetail.record import SERVERS_SEPARATOR
from yafs_safetail.results.claims import claim_holds
from yafs_safetail.results.files import REQUESTS_FILE, read_requests_csv
from yafs_safetail.results.paper import PAPER_CLAIMS
from yafs_safetail.results.reproduction import RUN_FOLDER
from yafs_safetail.results.run_json import WORLD_OVERRIDES_KEY, read_run_json
from yafs_safetail.results.world_bounds import SERVER_CLAIMS
from yafs_safetail.runs.most_zeros import (
    DEFAULT_KEY,
    FIT_STEPS,
    KEYS,
    MostZeros,
    MostZerosError,
    RequestTable,
    apply_most_zeros,
    fit_for,
    fit_most_zeros,
    fit_world_table,
    joined,
    request_table,
    run_test_world,
)
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.world import WORLD_OVERRIDES

logger = logging.getLogger(__name__)

#: Issue 48's goals: SafeTail's share of zero rewards no more than this below the policy's...
ZERO_SHARE_MARGIN = 0.05
#: ...and its access rate no more than this above the policy's.
ACCESS_MARGIN = 0.05
#: A recorded reward equals the redrawn world's to float rounding (the CSV keeps every digit).
_SAME_REWARD = 1e-9


class MethodOptimumError(MostZerosError):
    """A run folder this comparison cannot read or redraw (one-line message naming the file)."""


# --------------------------------------------------------------------------------------------
# Figures of a policy on one seed, and over seeds


@dataclass(frozen=True)
class SeedFigures:
    """A policy's decisions on one seed's test requests.

    Attributes:
        seed: the seed.
        zero_share: the share of requests whose Eq. 5 reward is exactly 0.
        mean_servers: servers per request.
        access_rate: ``mean_servers`` / n.
        median_servers, min_servers, max_servers: of the servers per request.
        window_means: servers per request averaged over consecutive windows of β requests (the
            paper's Fig. (e) points; a shorter last window included, as ``results.stats``).
        mean_target_s: τ averaged over the requests.
    """

    seed: int
    zero_share: float
    mean_servers: float
    access_rate: float
    median_servers: float
    min_servers: int
    max_servers: int
    window_means: tuple[float, ...]
    mean_target_s: float

    def summary_row(self) -> pd.DataFrame:
        """A one-row summary with SafeTail's name, so that ``claims.claim_holds`` reads these
        decisions as it reads SafeTail's."""
        return pd.DataFrame([{
            "method": SAFETAIL, "mean_target_s": self.mean_target_s,
            "mean_n_selected": self.mean_servers, "median_n_selected": self.median_servers,
            "min_n_selected": self.min_servers, "max_n_selected": self.max_servers,
            "min_window_n_selected": min(self.window_means),
            "max_window_n_selected": max(self.window_means)}])


def seed_figures(seed: int, actions: np.ndarray, table: RequestTable, beta: int) -> SeedFigures:
    """:class:`SeedFigures` of ``actions`` taken on ``table``'s requests (in step order)."""
    n_servers = table.loads.shape[1]
    servers = membership_matrix(n_servers).sum(axis=1).astype(float)[actions]
    earned = table.reward[np.arange(len(actions)), actions]
    windows = tuple(float(servers[i:i + beta].mean()) for i in range(0, len(servers), beta))
    return SeedFigures(seed, float(np.mean(earned == 0.0)), float(servers.mean()),
                       float(servers.mean() / n_servers), float(np.median(servers)),
                       int(servers.min()), int(servers.max()), windows,
                       float(table.target_s.mean()))


def server_claims(use_case: int) -> tuple[str, ...]:
    """The keys of ``use_case``'s claims about how many servers SafeTail uses."""
    return tuple(c.key for c in PAPER_CLAIMS if c.use_case == use_case and c.key in SERVER_CLAIMS)


@dataclass(frozen=True)
class Optimum:
    """The most-zeros policy of one use case over seeds.

    Attributes:
        use_case: 1, 2 or 3.
        key: what it is keyed on.
        fit_seeds: the seeds it was fitted on.
        seeds: one :class:`SeedFigures` per seed it was measured on.
    """

    use_case: int
    key: str
    fit_seeds: tuple[int, ...]
    seeds: tuple[SeedFigures, ...]

    @property
    def zero_share(self) -> float:
        """The mean over seeds of the share of zero rewards."""
        return float(np.mean([s.zero_share for s in self.seeds]))

    @property
    def access_rate(self) -> float:
        """The mean over seeds of the access rate."""
        return float(np.mean([s.access_rate for s in self.seeds]))

    @property
    def mean_servers(self) -> float:
        return float(np.mean([s.mean_servers for s in self.seeds]))

    @property
    def window_range(self) -> tuple[float, float]:
        """The smallest and largest β-window mean over every seed."""
        return (min(min(s.window_means) for s in self.seeds),
                max(max(s.window_means) for s in self.seeds))

    def claim_share(self, key: str) -> float:
        """The share of seeds in which the policy makes server claim ``key`` hold."""
        verdicts = [claim_holds(key, s.summary_row()) for s in self.seeds]
        return float(np.mean([bool(v) for v in verdicts]))

    def reaches(self, key: str) -> bool:
        """Whether the policy makes claim ``key`` hold in most seeds (the scorecard's verdict)."""
        return self.claim_share(key) > 0.5

    def claim_figure(self, key: str) -> str:
        """The policy's figures a server claim reads, in words."""
        low, high = self.window_range
        windows = f"β-window means {low:.2f}–{high:.2f}"
        if key == "mean_servers_2_to_3":
            fewest = min(s.min_servers for s in self.seeds)
            return f"{self.mean_servers:.2f} servers per request, fewest {fewest}"
        if key == "mostly_1_to_2_servers":
            median = float(np.median([s.median_servers for s in self.seeds]))
            return f"median {median:g} servers, {windows}"
        return windows


def optimum_for_seeds(use_case: int, seeds: Sequence[int], *, preset: str = "paper",
                      steps_scale: float = 1.0, key: str = DEFAULT_KEY,
                      fit_seeds: Sequence[int] | None = None, fit_steps: int = FIT_STEPS,
                      policy: MostZeros | None = None) -> Optimum:
    """The most-zeros policy of ``use_case`` on the test requests of ``seeds``, as runs of
    ``preset`` at ``steps_scale`` draw them (``policy``: one already fitted for this world)."""
    base = ExperimentConfig(use_case=use_case, preset=preset, steps_scale=steps_scale)
    chosen = policy or fit_for(base, key, fit_seeds, fit_steps)
    figures = []
    for seed in seeds:
        world, delta, beta = run_test_world(dataclasses.replace(base, seed=seed))
        table = request_table(world, delta)
        figures.append(seed_figures(seed, apply_most_zeros(chosen, table), table, beta))
    return Optimum(use_case, chosen.key, _fit_seeds(fit_seeds), tuple(figures))


def _fit_seeds(fit_seeds: Sequence[int] | None) -> tuple[int, ...]:
    return tuple(seed_set("world_calibration") if fit_seeds is None else fit_seeds)


# --------------------------------------------------------------------------------------------
# Run folders: SafeTail's side, and the policy on the same requests


@dataclass(frozen=True)
class SafeTailFigures:
    """SafeTail's test phase in one run folder.

    Attributes:
        seed: the run's seed.
        zero_share: the share of its test requests whose recorded reward is exactly 0.
        mean_servers: servers per request.
        access_rate: the mean of its recorded access rates.
    """

    seed: int
    zero_share: float
    mean_servers: float
    access_rate: float


def _safetail_test_rows(folder: Path) -> pd.DataFrame:
    """SafeTail's test rows of a run's ``requests.csv``, in step order."""
    requests = read_requests_csv(folder / REQUESTS_FILE)
    rows = requests[(requests["method"] == SAFETAIL) & (requests["phase"] == "test")]
    if rows.empty:
        raise MethodOptimumError(f"{folder / REQUESTS_FILE}: no {SAFETAIL} test-phase rows")
    if rows["reward"].isna().any():
        raise MethodOptimumError(f"{folder / REQUESTS_FILE}: column reward: {SAFETAIL} test rows "
                                 "without a reward")
    return rows.sort_values("step", kind="stable")


def safetail_side(folder: str | Path, rows: pd.DataFrame | None = None) -> SafeTailFigures:
    """SafeTail's share of zero rewards and access rate from a run folder's ``requests.csv``
    (``rows``: its SafeTail test rows, already read).

    Raises:
        ResultsFileError: ``requests.csv`` or ``run.json`` missing or malformed.
        MethodOptimumError: no SafeTail test rows, or a missing reward.
    """
    folder = Path(folder)
    run = read_run_json(folder)
    part = _safetail_test_rows(folder) if rows is None else rows
    return SafeTailFigures(run.seed, float(np.mean(part["reward"].to_numpy(float) == 0.0)),
                           float(part["n_selected"].mean()), float(part["access_rate"].mean()))


def run_config(folder: str | Path) -> ExperimentConfig:
    """The configuration whose test world a run folder's run faced, from its ``run.json``:
    use case, preset, seed, steps scale and the world's overrides.

    Raises:
        ResultsFileError: ``run.json`` missing or malformed.
        MethodOptimumError: an override this configuration does not know, or a bad steps scale.
    """
    folder = Path(folder)
    run = read_run_json(folder)
    overrides = run.extra.get(WORLD_OVERRIDES_KEY) or {}
    scale = run.extra.get("steps_scale", 1.0)
    if not isinstance(overrides, dict) or not isinstance(scale, int | float) or isinstance(scale, bool):
        raise MethodOptimumError(f"{folder / 'run.json'}: keys {WORLD_OVERRIDES_KEY}, steps_scale: "
                                 "expected an object and a number")
    try:
        return ExperimentConfig(use_case=run.use_case, preset=run.preset, seed=run.seed,
                                steps_scale=float(scale), **overrides)
    except TypeError as error:
        raise MethodOptimumError(f"{folder / 'run.json'}: {WORLD_OVERRIDES_KEY}: {error}") from None


def _check_same_requests(folder: Path, rows: pd.DataFrame, table: RequestTable, n_servers: int) -> None:
    """The redrawn world is the run's: the same τ on every test request, and the reward
    SafeTail recorded is that of the subset it chose."""
    file = folder / REQUESTS_FILE
    if len(rows) != table.n_requests:
        raise MethodOptimumError(f"{file}: {len(rows)} {SAFETAIL} test requests, the world redrawn "
                                 f"from run.json has {table.n_requests}")
    if not np.allclose(rows["target_s"].to_numpy(float), table.target_s, rtol=0.0, atol=_SAME_REWARD):
        raise MethodOptimumError(f"{file}: column target_s: not the world redrawn from run.json "
                                 "(a run with a topology, traces or timing of its own?)")
    try:
        actions = [action_of([int(s) for s in text.split(SERVERS_SEPARATOR)], n_servers)
                   for text in rows["servers"]]
    except ValueError:
        raise MethodOptimumError(f"{file}: column servers: not server indices 0..{n_servers - 1} "
                                 f"separated by {SERVERS_SEPARATOR!r}") from None
    recorded = rows["reward"].to_numpy(float)
    redrawn = table.reward[np.arange(len(actions)), actions]
    if not np.allclose(recorded, redrawn, rtol=0.0, atol=_SAME_REWARD):
        raise MethodOptimumError(f"{file}: column reward: {SAFETAIL}'s rewards are not those of the "
                                 "world redrawn from run.json (failures, a moving user or "
                                 "requests closer than a minute?)")


_RUN_FOLDER = re.compile(re.escape(RUN_FOLDER).replace(r"\{use_case\}", r"(?P<use_case>\d+)")
                         .replace(r"\{preset\}", r"(?P<preset>[^/]+)")
                         .replace(r"\{seed\}", r"(?P<seed>\d+)") + "$")


def run_folders(out: str | Path, preset: str = "paper") -> dict[tuple[int, int], Path]:
    """Every run folder of ``preset`` in a reproduction's folder, by (use case, seed).

    Raises:
        MethodOptimumError: the folder does not exist or holds no run of ``preset``.
    """
    out = Path(out)
    if not out.is_dir():
        raise MethodOptimumError(f"{out}: folder not found")
    found = {}
    for path in sorted(out.glob(RUN_FOLDER.format(use_case="*", preset=preset, seed="*"))):
        match = _RUN_FOLDER.search(path.relative_to(out).as_posix())
        if match and path.is_dir():
            found[(int(match["use_case"]), int(match["seed"]))] = path
    if not found:
        raise MethodOptimumError(f"{out}: no run folder {RUN_FOLDER.format(use_case='<N>', preset=preset, seed='<S>')}")
    return dict(sorted(found.items()))


@dataclass(frozen=True)
class Comparison:
    """SafeTail beside the most-zeros policy on the same test requests, one use case.

    Attributes:
        use_case: 1, 2 or 3.
        safetail: SafeTail's figures per seed.
        optimum: the policy's on the same seeds' requests.
    """

    use_case: int
    safetail: tuple[SafeTailFigures, ...]
    optimum: Optimum

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(s.seed for s in self.safetail)

    @property
    def safetail_zero_share(self) -> float:
        return float(np.mean([s.zero_share for s in self.safetail]))

    @property
    def safetail_access_rate(self) -> float:
        return float(np.mean([s.access_rate for s in self.safetail]))

    @property
    def zero_share_gap(self) -> float:
        """SafeTail's share of zero rewards minus the policy's."""
        return self.safetail_zero_share - self.optimum.zero_share

    @property
    def access_gap(self) -> float:
        """SafeTail's access rate minus the policy's."""
        return self.safetail_access_rate - self.optimum.access_rate

    @property
    def zero_share_met(self) -> bool:
        """Within :data:`ZERO_SHARE_MARGIN` of the policy's share (or above it: earning more
        zeros than the policy is no shortfall of the learner)."""
        return self.zero_share_gap >= -ZERO_SHARE_MARGIN

    @property
    def access_met(self) -> bool:
        """At most :data:`ACCESS_MARGIN` above the policy's access rate."""
        return self.access_gap <= ACCESS_MARGIN


def compare(runs: Mapping[tuple[int, int], Path], key: str = DEFAULT_KEY,
            fit_seeds: Sequence[int] | None = None, fit_steps: int = FIT_STEPS) -> list[Comparison]:
    """Per use case, SafeTail in ``runs`` (by (use case, seed)) beside the most-zeros policy on
    the same requests. The policy is fitted once per use case and world; every run's redrawn
    test world is checked against its ``requests.csv`` first.

    Raises:
        ResultsFileError: a run's file missing or malformed.
        MethodOptimumError: a run this comparison cannot redraw, or whose requests differ.
    """
    by_use_case: dict[int, list[Path]] = {}
    for (use_case, _), folder in sorted(runs.items()):
        by_use_case.setdefault(use_case, []).append(folder)
    comparisons = []
    policies: dict[tuple[object, ...], MostZeros] = {}
    for use_case, folders in by_use_case.items():
        safetail, figures = [], []
        for folder in folders:
            config = run_config(folder)
            rows = _safetail_test_rows(folder)
            world, delta, beta = run_test_world(config)
            table = request_table(world, delta)
            _check_same_requests(folder, rows, table, world.n_servers)
            # One fit per world: the same use case, preset and overrides share it.
            world_id = (config.use_case, config.preset, *_world_overrides(config))
            if world_id not in policies:
                policies[world_id] = fit_for(config, key, fit_seeds, fit_steps)
            actions = apply_most_zeros(policies[world_id], table)
            figures.append(seed_figures(config.seed, actions, table, beta))
            safetail.append(safetail_side(folder, rows))
        comparisons.append(Comparison(use_case, tuple(safetail),
                                      Optimum(use_case, key, _fit_seeds(fit_seeds), tuple(figures))))
    return comparisons


def _world_overrides(config: ExperimentConfig) -> Iterable[object]:
    return tuple(getattr(config, name) for name in WORLD_OVERRIDES)


# --------------------------------------------------------------------------------------------
# Which key: measured on world-calibration seeds the policy was not fitted on


def key_zero_shares(use_case: int, fit_seeds: Sequence[int], score_seeds: Sequence[int],
                    n_steps: int = FIT_STEPS, preset: str = "paper") -> dict[str, tuple[float, float]]:
    """Per key of :data:`KEYS`: (share of zero rewards, access rate) of the policy fitted on
    ``fit_seeds``' test worlds and applied to ``score_seeds``', ``n_steps`` requests each."""
    config = ExperimentConfig(use_case=use_case, preset=preset)
    fit = joined([fit_world_table(config, seed, n_steps) for seed in fit_seeds])
    scored = joined([fit_world_table(config, seed, n_steps) for seed in score_seeds])
    n_servers = scored.loads.shape[1]
    servers = membership_matrix(n_servers).sum(axis=1)
    shares = {}
    for key in KEYS:
        actions = apply_most_zeros(fit_most_zeros(fit, key), scored)
        zero = float(np.mean(scored.reward[np.arange(len(actions)), actions] == 0.0))
        shares[key] = (zero, float(servers[actions].mean() / n_servers))
    return shares
