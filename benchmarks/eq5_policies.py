"""What Eq. 5 rewards in the default world: the policies a perfect learner would reach.

A learner-free measurement (no TensorFlow), on the world-calibration seeds only. For each use
case, every request's latency under each of the 2^n - 1 subsets is read from the world's
per-copy table (one request a minute, so every copy has ended before the next request; the
fastest copy answers, or the on-device fallback when every chosen server refuses). Eq. 5 with
Table I's δ and the request's τ scores it. The policies below are fitted on the even requests of
every seed and scored on the odd ones. They are keyed on what SafeTail's state shows that moves
latency most: the active users of each server (``--key loads``). ``--key loads+input`` adds
the input size's tercile, and ``loads+input+uplink`` adds the user's uplink tercile. A finer
key sees more, but each key then has fewer requests to fit on.

* ``expected reward``: for each load vector, the subset with the highest mean Eq. 5 reward.
  The original code's Q-style targets approach this (docs/deviations.md D17).
* ``most zeros``: the subset that earns exactly 0 most often. §III's target vector
  approaches this.
* ``best fixed``: the one subset with the highest mean reward, whatever the state.
* ``hindsight``: per request the subset with the best reward it actually earned. Not a
  policy, since it knows the draws; it bounds every policy.

Each row gives the mean servers per request and the access rate (goal ≤ 0.5). It also gives
the share of requests sent the policy's most common subset, the range of its β-request window
means (UC1's claim: every one in [1, 3] and not all equal) and the mean Eq. 5 reward. A load
vector seen only among the odd requests gets the best fixed subset.

    python benchmarks/eq5_policies.py [--seeds 1000,...,1009] [--steps 20000] [--key loads]

About 5 s on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

import numpy as np

from yafs_safetail.edge.calibration import seed_set
from yafs_safetail.edge.world import DEFAULT_EPISODE_STEPS, EdgeWorld
from yafs_safetail.methods.safetail.spaces import membership_matrix
from yafs_safetail.settings.experiment import ExperimentConfig
from yafs_safetail.settings.world_recipe import world_recipe


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


def _per_key_choice(keys: np.ndarray, fit: np.ndarray, scores: np.ndarray, fallback_action: int) -> np.ndarray:
    """For each key, the action with the highest mean score over the fit requests with it."""
    n_keys = int(keys.max()) + 1
    sums = np.zeros((n_keys, scores.shape[1]))
    np.add.at(sums, keys[fit], scores[fit])
    counts = np.bincount(keys[fit], minlength=n_keys)
    best = np.argmax(sums / np.maximum(counts, 1)[:, None], axis=1)
    return np.where(counts > 0, best, fallback_action)


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


#: What a policy may key on: each server's active users, then the request's input size and the
#: user's uplink, each cut into terciles over all the requests measured.
KEYS = ("loads", "loads+input", "loads+input+uplink")


def _terciles(values: np.ndarray) -> np.ndarray:
    return np.digitize(values, np.quantile(values, [1 / 3, 2 / 3]))


def measure(use_case_number: int, seeds: list[int], n_steps: int, key: str = "loads") -> dict[str, str]:
    """Every policy's row for one use case, over ``seeds``' test worlds (the default run's world
    and preset, ``n_steps`` requests each)."""
    recipe = world_recipe(ExperimentConfig(use_case=use_case_number))
    preset = recipe.learner
    n_servers = recipe.parts.scenario.n_servers
    members = membership_matrix(n_servers).astype(bool)
    n_selected = members.sum(axis=1)
    rewards, loads, input_bytes, uplink_bps = [], [], [], []
    for seed in seeds:
        world = recipe.parts.draw(n_steps, seed, "test", episode_steps=preset.episode_steps)
        latency_s = subset_latencies_s(world, members)
        rewards.append(eq5_rewards(latency_s, world.target_s, n_selected, world.n_servers, preset.delta))
        loads.append(world.background_users)
        input_bytes.append(world.input_bytes)
        uplink_bps.append(world.user_uplink_bps)
    reward = np.concatenate(rewards)
    features = [np.concatenate(loads)]
    if key != "loads":
        features.append(_terciles(np.concatenate(input_bytes))[:, None])
    if key == "loads+input+uplink":
        features.append(_terciles(np.concatenate(uplink_bps))[:, None])
    _, keys = np.unique(np.hstack(features), axis=0, return_inverse=True)
    keys = keys.ravel()
    fit = np.zeros(len(reward), dtype=bool)
    fit[::2] = True
    held = ~fit
    best_fixed = int(np.argmax(reward[fit].mean(axis=0)))
    policies: dict[str, Callable[[], np.ndarray]] = {
        "expected_reward": lambda: _per_key_choice(keys, fit, reward, best_fixed)[keys[held]],
        "most_zeros": lambda: _per_key_choice(keys, fit, (reward == 0.0).astype(float), best_fixed)[keys[held]],
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
