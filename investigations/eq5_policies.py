"""What Eq. 5 rewards in the default world: the policies a perfect learner would reach.

A learner-free measurement (no TensorFlow), on the world-calibration seeds only. For each use
case, every request's latency under each of the 2^n - 1 subsets is read from the world's
per-copy table (one request a minute, so every copy has ended before the next request; the
fastest copy answers, or the on-device fallback when every chosen server refuses). Eq. 5 with
Table I's δ and the request's τ scores it. The policies below are fitted on the even requests of
every seed and scored on the odd ones. They are keyed on what SafeTail's state shows that moves
latency most: the active users of each server (``--key loads``). ``--key loads+input`` adds
the input size's tercile, ``loads+input+uplink`` the user's uplink tercile and
``loads+input+uplink+downlink`` the downlink's. A finer key sees more, but each key then has
fewer requests to fit on. The rewards and the per-key fit are ``yafs_safetail.runs.method_optimum``'s,
which also measures the ``most zeros`` policy on a run's own test requests
(``investigations/learner_vs_optimum.py``).

* ``expected reward``: for each load vector, the subset with the highest mean Eq. 5 reward.
  The original code's Q-style targets approach this (docs/deviations.md D18).
* ``most zeros``: the subset that earns exactly 0 most often. §III's target vector
  approaches this.
* ``best fixed``: the one subset with the highest mean reward, whatever the state.
* ``hindsight``: per request the subset with the best reward it actually earned. Not a
  policy, since it knows the draws; it bounds every policy.

Each row gives the mean servers per request and the access rate (goal ≤ 0.5). It also gives
the share of requests sent the policy's most common subset, the range of its β-request window
means (UC1's claim: every one in [1, 3] and not all equal) and the mean Eq. 5 reward. A load
vector seen only among the odd requests gets the best fixed subset.

    python investigations/eq5_policies.py [--seeds 1000,...,1009] [--steps 20000] [--key loads]

About 5 s on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

import numpy as np

from yafs_safetail.edge.calibration import seed_set
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS
from yafs_safetail.methods.safetail.spaces import membership_matrix
from yafs_safetail.runs.most_zeros import (
    KEYS,
    joined,
    key_columns,
    key_features,
    per_key_choice,
    request_table,
    tercile_cuts,
)
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.worlds.recipe import world_recipe


def describe(actions: np.ndarray, rewards: np.ndarray, n_selected: np.ndarray, n_servers: int,
             beta: int) -> str:
    """One policy's row: servers, access rate, its most common subset's share, window means."""
    servers = n_selected[actions].astype(float)
    n_windows = len(servers) // beta
    windows = servers[: n_windows * beta].reshape(n_windows, beta).mean(axis=1)
    top_share = np.bincount(actions).max() / len(actions)
    return (f"servers={servers.mean():.2f} access={servers.mean() / n_servers:.2f} "
            f"top_subset={top_share:.2f} windows={windows.min():.2f}-{windows.max():.2f} "
            f"reward={rewards.mean():.5f}")


def measure(use_case_number: int, seeds: list[int], n_steps: int, key: str = "loads") -> dict[str, str]:
    """Every policy's row for one use case, over ``seeds``' test worlds (the default run's world
    and preset, ``n_steps`` requests each)."""
    recipe = world_recipe(ExperimentConfig(use_case=use_case_number))
    preset = recipe.learner
    n_servers = recipe.parts.scenario.n_servers
    n_selected = membership_matrix(n_servers).astype(bool).sum(axis=1)
    table = joined([request_table(recipe.parts.draw(n_steps, seed, "test", episode_steps=preset.episode_steps),
                                  preset.delta) for seed in seeds])
    reward = table.reward
    # The terciles over every request measured, the fit's and the scored ones alike.
    cuts = {name: tercile_cuts(table.features[name]) for name in key_features(key)}
    _, keys = np.unique(key_columns(table, key, cuts), axis=0, return_inverse=True)
    keys = keys.ravel()
    fit = np.zeros(len(reward), dtype=bool)
    fit[::2] = True
    held = ~fit
    best_fixed = int(np.argmax(reward[fit].mean(axis=0)))
    policies: dict[str, Callable[[], np.ndarray]] = {
        "expected_reward": lambda: per_key_choice(keys, fit, reward, best_fixed)[keys[held]],
        "most_zeros": lambda: per_key_choice(keys, fit, (reward == 0.0).astype(float), best_fixed)[keys[held]],
        "best_fixed": lambda: np.full(int(held.sum()), best_fixed),
        "hindsight": lambda: np.argmax(reward[held], axis=1),
    }
    rows = {}
    for name, choose in policies.items():
        actions = choose()
        earned = reward[held][np.arange(len(actions)), actions]
        rows[name] = describe(actions, earned, n_selected, n_servers, preset.beta)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default=None,
                        help="world-calibration seeds, comma-separated (default: seed_sets.json's)")
    parser.add_argument("--steps", type=int, default=20000, help="requests per seed (default 20000)")
    parser.add_argument("--key", choices=KEYS, default="loads",
                        help="what a policy is keyed on (default loads: each server's active users)")
    args = parser.parse_args(argv)
    try:
        seeds = ([int(s) for s in args.seeds.split(",")] if args.seeds
                 else seed_set("world_calibration"))
    except ValueError:
        parser.error(f"--seeds: expected comma-separated integers, got {args.seeds!r}")
    if args.steps < 2 * DEFAULT_EPISODE_STEPS:
        parser.error(f"--steps: expected at least {2 * DEFAULT_EPISODE_STEPS}, got {args.steps}")
    for use_case in (1, 2, 3):
        for name, row in measure(use_case, seeds, args.steps, args.key).items():
            print(f"uc{use_case} {name:16s} {row}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
