"""The "most zeros" policy: what §III's training target rewards, learned without a learner.

Under §III's target vector SafeTail learns, for each state, the subset that most often earns an
Eq. 5 reward of exactly 0: one server that meets τ, or all n when none would (docs/deviations.md
D18). This module scores every subset of every request of a world by Eq. 5, from the world's
per-copy table (:func:`request_table`), fits that policy per key on the world-calibration seeds
(:func:`fit_most_zeros`, :func:`fit_for`) and applies it to other requests
(:func:`apply_most_zeros`). ``runs.method_optimum`` sets it beside a run's SafeTail;
``investigations/eq5_policies.py`` beside the other policies Eq. 5 suggests.

The key (:data:`DEFAULT_KEY`, ``loads+input+uplink``). SafeTail's state
(``methods/safetail/spaces.py``) holds, per server, its bandwidths, memory and CPU utilisation,
active users and median propagation; per request, the input size, the estimated output size and
Γ; and the user's location and bandwidths. A table cannot key on all of it, so the key keeps
what decides whether one copy meets τ: each server's active users (they set its compute time,
its share of the bandwidth and whether it refuses; its memory and CPU utilisation are functions
of them, and its median propagation and the user's location are fixed in the default world, so
a server's place in the key carries them), the input size (it sets the transfers and τ, Eq. 4)
and the user's uplink (it bounds every copy's upload and enters τ), each cut into terciles at
the fit requests' quantiles. A key the fit never saw backs off to ``loads+input``, then to
``loads``, then to the subset with the most zeros overall, as a network answers an unseen state
from its neighbours. ``python investigations/learner_vs_optimum.py --keys`` measures each key's
zero share on world-calibration seeds it was not fitted on: a finer key (the user's downlink
too, :data:`KEYS`' last) has fewer fit requests per key than it gains, and ``loads+input`` earns
a few thousandths more zeros than this key. The uplink stays in it all the same: SafeTail sees
it and it moves τ and every copy's upload, so a learner can use it where a table runs short of
requests, and the back-off keeps the table's thinner keys from costing more than that.

Learner-free: no TensorFlow; a use case's fit takes a few seconds.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from yafs_safetail.edge.calibration import seed_set
from yafs_safetail.edge.world import EdgeWorld
from yafs_safetail.methods.safetail.spaces import membership_matrix
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.worlds.recipe import TEST, WorldRecipe, world_recipe

logger = logging.getLogger(__name__)

#: What a policy may key on: each server's active users, then request and user features in this
#: order, each cut into terciles. A key's back-off chain is its prefixes, shortest last.
FEATURES: tuple[str, ...] = ("input", "uplink", "downlink")
KEYS: tuple[str, ...] = ("loads", "loads+input", "loads+input+uplink", "loads+input+uplink+downlink")
DEFAULT_KEY = "loads+input+uplink"
#: Requests per world-calibration seed the policy is fitted on (``eq5_policies.py``'s default).
FIT_STEPS = 20000
_N_BINS = 3


class MostZerosError(ValueError):
    """A world the policy cannot be measured in (one-line message)."""


# --------------------------------------------------------------------------------------------
# Every subset's reward


def subset_latencies_s(world: EdgeWorld, members: np.ndarray) -> np.ndarray:
    """(requests, actions): the fastest chosen copy, or the fallback when every one refuses."""
    table = world.copy_latency_table_s()
    chosen = np.where(members[None, :, :], table[:, None, :], np.inf)
    fastest = chosen.min(axis=2)
    return np.where(np.isfinite(fastest), fastest, world.fallback_latency_s)


def eq5_rewards(latency_s: np.ndarray, target_s: np.ndarray, n_selected: np.ndarray, n_servers: int,
                delta: float) -> np.ndarray:
    """Eq. 5 for a (requests, actions) latency table, case by case as ``reward.reward``."""
    tau = target_s[:, None]
    k = n_selected[None, :]
    met = latency_s < tau
    missed_penalty = -delta * np.exp(n_servers - k) * (k < n_servers)
    met_penalty = -delta * np.exp(np.minimum(latency_s - tau, 0.0)) * (k > 1)
    rewards = np.where(met, met_penalty, missed_penalty)
    return np.where(latency_s == tau, 0.0, rewards)


def per_key_choice(keys: np.ndarray, fit: np.ndarray, scores: np.ndarray, fallback_action: int) -> np.ndarray:
    """For each key, the action with the highest mean score over the fit requests with it
    (the lowest action among equals); ``fallback_action`` for a key no fit request has."""
    n_keys = int(keys.max()) + 1
    sums = np.zeros((n_keys, scores.shape[1]))
    np.add.at(sums, keys[fit], scores[fit])
    counts = np.bincount(keys[fit], minlength=n_keys)
    best = np.argmax(sums / np.maximum(counts, 1)[:, None], axis=1)
    return np.where(counts > 0, best, fallback_action)


def tercile_cuts(values: np.ndarray) -> np.ndarray:
    """The two cut points that split ``values`` into terciles (``np.digitize`` applies them)."""
    return np.quantile(values, [k / _N_BINS for k in range(1, _N_BINS)])


@dataclass(frozen=True)
class RequestTable:
    """What a policy of this module reads from a world's requests, and every subset's reward.

    Attributes:
        reward: Eq. 5 reward per (request, action).
        loads: each server's active users when the request is issued, per (request, server).
        features: per :data:`FEATURES` name, its value per request (input bytes, the user's
            uplink and downlink bps).
        target_s: τ per request.
        max_load: the most active users a server can show (its load limit).
    """

    reward: np.ndarray
    loads: np.ndarray
    features: Mapping[str, np.ndarray]
    target_s: np.ndarray
    max_load: int

    @property
    def n_requests(self) -> int:
        return int(self.reward.shape[0])


def request_table(world: EdgeWorld, delta: float) -> RequestTable:
    """:class:`RequestTable` of every request of ``world`` (δ: Table I's, the learner's)."""
    members = membership_matrix(world.n_servers).astype(bool)
    n_selected = members.sum(axis=1)
    latency_s = subset_latencies_s(world, members)
    return RequestTable(
        reward=eq5_rewards(latency_s, world.target_s, n_selected, world.n_servers, delta),
        loads=world.background_users,
        features={"input": world.input_bytes, "uplink": world.user_uplink_bps,
                  "downlink": world.user_downlink_bps},
        target_s=world.target_s, max_load=world.max_load)


def joined(tables: Sequence[RequestTable]) -> RequestTable:
    """Several worlds' requests as one table, in order."""
    return RequestTable(
        reward=np.concatenate([t.reward for t in tables]),
        loads=np.concatenate([t.loads for t in tables]),
        features={name: np.concatenate([t.features[name] for t in tables]) for name in FEATURES},
        target_s=np.concatenate([t.target_s for t in tables]),
        max_load=max(t.max_load for t in tables))


def key_features(key: str) -> tuple[str, ...]:
    """The features a key reads after the loads (``loads+input`` -> ``("input",)``).

    Raises:
        ValueError: not one of :data:`KEYS`.
    """
    if key not in KEYS:
        raise ValueError(f"key {key!r}: expected one of {', '.join(KEYS)}")
    return tuple(key.split("+")[1:])


def key_columns(table: RequestTable, key: str, cuts: Mapping[str, np.ndarray]) -> np.ndarray:
    """(requests, n + features): the loads, then each feature's tercile under ``cuts``."""
    columns = [table.loads.astype(np.int64)]
    columns += [np.digitize(table.features[name], cuts[name])[:, None] for name in key_features(key)]
    return np.hstack(columns)


# --------------------------------------------------------------------------------------------
# The "most zeros" policy


@dataclass(frozen=True)
class MostZeros:
    """The learner-free policy §III's target vector approaches, fitted per key.

    Attributes:
        key: one of :data:`KEYS`.
        cuts: each feature's tercile cut points, from the fit requests.
        levels: per prefix of the key, shortest first (``loads``, ``loads+input``, ...): the
            sorted codes of the keys the fit saw and each one's action.
        fallback_action: the action with the most zeros over every fit request (a load vector
            the fit never saw).
        max_load: the largest number of active users a server can show (the codes' radix).
        n_fit_requests: how many requests it was fitted on.
    """

    key: str
    cuts: Mapping[str, np.ndarray]
    levels: tuple[tuple[np.ndarray, np.ndarray], ...]
    fallback_action: int
    max_load: int
    n_fit_requests: int


def _codes(table: RequestTable, features: Sequence[str], cuts: Mapping[str, np.ndarray],
           max_load: int) -> np.ndarray:
    """One integer per request for the key of the loads and ``features`` (mixed radix)."""
    loads = table.loads.astype(np.int64)
    if loads.size and (loads.min() < 0 or loads.max() > max_load):
        raise ValueError(f"active users outside 0..{max_load}")
    radix = max_load + 1
    code = loads @ (radix ** np.arange(loads.shape[1], dtype=np.int64))
    for name in features:
        code = code * _N_BINS + np.digitize(table.features[name], cuts[name])
    return np.asarray(code, dtype=np.int64)


def fit_most_zeros(table: RequestTable, key: str = DEFAULT_KEY) -> MostZeros:
    """The most-zeros policy fitted on ``table``'s requests.

    Args:
        table: the fit requests (:func:`request_table` of the world-calibration seeds' worlds).
        key: one of :data:`KEYS`.

    Raises:
        ValueError: an unknown key, or an empty table.
    """
    features = key_features(key)
    if table.n_requests == 0:
        raise ValueError("no requests to fit the most-zeros policy on")
    zeros = (table.reward == 0.0).astype(float)
    cuts = {name: tercile_cuts(table.features[name]) for name in features}
    levels = []
    for size in range(len(features) + 1):
        codes = _codes(table, features[:size], cuts, table.max_load)
        seen, keys = np.unique(codes, return_inverse=True)
        choice = per_key_choice(keys.ravel(), np.ones(len(codes), dtype=bool), zeros, 0)
        levels.append((seen, choice))
    return MostZeros(key, cuts, tuple(levels), int(np.argmax(zeros.mean(axis=0))), table.max_load,
                     table.n_requests)


def apply_most_zeros(policy: MostZeros, table: RequestTable) -> np.ndarray:
    """The policy's action for every request of ``table``: the finest level of its key the fit
    saw, else the fallback."""
    features = key_features(policy.key)
    actions = np.full(table.n_requests, policy.fallback_action, dtype=np.int64)
    for size, (seen, choice) in enumerate(policy.levels):
        if not len(seen):
            continue
        codes = _codes(table, features[:size], policy.cuts, policy.max_load)
        where = np.minimum(np.searchsorted(seen, codes), len(seen) - 1)
        found = seen[where] == codes
        actions = np.where(found, choice[where], actions)
    return actions


# --------------------------------------------------------------------------------------------
# The worlds: the fit's and a run's


def _check_table_world(recipe: WorldRecipe, what: str) -> None:
    """The per-copy table is the simulation only with every server up and the user still."""
    if recipe.failures.enabled or recipe.mobility is not None:
        raise MostZerosError(f"{what}: the most-zeros policy reads the world's per-copy "
                                 "table, which is the simulation only with every server up and "
                                 "the user still (no failures, no mobility)")


def fit_world_table(config: ExperimentConfig, seed: int, n_steps: int = FIT_STEPS) -> RequestTable:
    """:class:`RequestTable` of ``seed``'s test world of ``config``'s use case, preset and
    world, ``n_steps`` requests (a fit world: not a run's length)."""
    recipe = world_recipe(config)  # the seed only picks the draws, not the recipe
    _check_table_world(recipe, f"use case {config.use_case}")
    world = recipe.parts.draw(n_steps, seed, TEST, episode_steps=recipe.learner.episode_steps,
                              step_interval_s=recipe.step_interval_s)
    return request_table(world, recipe.learner.delta)


def fit_for(config: ExperimentConfig, key: str = DEFAULT_KEY, fit_seeds: Sequence[int] | None = None,
            fit_steps: int = FIT_STEPS) -> MostZeros:
    """The most-zeros policy of ``config``'s use case, preset and world, fitted on the
    world-calibration seeds (default) or ``fit_seeds``."""
    seeds = list(seed_set("world_calibration") if fit_seeds is None else fit_seeds)
    tables = [fit_world_table(config, seed, fit_steps) for seed in seeds]
    logger.info("use case %d: most-zeros policy keyed on %s, fitted on %d requests of seeds %s",
                config.use_case, key, sum(t.n_requests for t in tables), seeds)
    return fit_most_zeros(joined(tables), key)


def run_test_world(config: ExperimentConfig) -> tuple[EdgeWorld, float, int]:
    """The test world a run of ``config`` draws (``WorldRecipe.make_world``), with its δ and β."""
    recipe = world_recipe(config)
    _check_table_world(recipe, f"use case {config.use_case}, seed {config.seed}")
    return recipe.make_world(TEST, config.seed), recipe.learner.delta, recipe.learner.beta
