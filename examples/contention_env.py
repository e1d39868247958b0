"""An outside agent in the contention world, compared with the sweep's methods on the same run.

The agent talks to ``yafs_safetail/SafeTailContention-v0`` only through Gymnasium: it reads the
observation dict (ω^t) and returns an action index (a subset of servers). Here it is a rule, the
two servers with the most free slots (ties: the nearer one), and, for scale, a uniformly random
agent; any agent (a Stable-Baselines3 model with ``observation="vector"``) plugs in the same
way. The environment's run is the one ``run_policy`` makes with the same settings and seed, so
the fixed methods below, run by ``run_policy`` on that world, see exactly the same requests.
The world is the load sweep's test world at one load (``experiments/load_sweep.py``'s defaults:
full servers queue copies, no background tenants; phase ``"test"``).

    python examples/contention_env.py                             # UC1, 50 users, load 0.5
    python examples/contention_env.py --load 0.9 --requests 4000 --seed 17
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium
import numpy as np

import yafs_safetail
from yafs_safetail.cli import run_cli
from yafs_safetail.contention.run import PolicyRun, run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionWorld
from yafs_safetail.methods.registry import make_baseline
from yafs_safetail.methods.safetail.spaces import action_of

FIXED_METHODS = ("MinLoad-2", "Tied", "Oracle")
COLUMNS = ("p50_s", "p99_s", "mean_n_selected", "fallback_rate")

Agent = Callable[[dict[str, np.ndarray]], int]


def most_free_pair(observation: dict[str, np.ndarray]) -> int:
    """The two servers with the most free slots; the nearer one first among equals."""
    free = observation["server_max_load"] - observation["server_active_users"]
    ranked = np.lexsort((observation["server_median_propagation_s"], -free))
    return action_of(ranked[:2].tolist(), free.shape[0])


def run_agent(env: gymnasium.Env, agent: Agent, seed: int) -> tuple[PolicyRun, float]:
    """One whole run with ``agent`` dispatching every request: the run and its total reward."""
    observation, _ = env.reset(seed=seed)
    total_reward, truncated = 0.0, False
    info: dict[str, Any] = {}
    while not truncated:
        observation, reward, _, truncated, info = env.step(agent(observation))
        total_reward += reward
    return info["run"], total_reward


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, default=1)
    parser.add_argument("--users", type=int, default=50)
    parser.add_argument("--load", type=float, default=0.5)
    parser.add_argument("--requests", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=17)
    args = parser.parse_args(argv)
    # The load sweep's world (its defaults differ from ContentionConfig's in these two).
    settings = {"use_case": args.uc, "users": args.users, "load": args.load, "n_requests": args.requests,
                "phase": "test", "queue": True, "background": False}

    env = gymnasium.make(yafs_safetail.CONTENTION_ENV_ID, **settings)
    random_actions = np.random.default_rng(args.seed)
    agents: dict[str, Agent] = {
        "most-free-pair": most_free_pair,
        "random": lambda _: int(random_actions.integers(env.action_space.n)),  # type: ignore[attr-defined]
    }
    rows = []
    for name, agent in agents.items():
        run, total_reward = run_agent(env, agent, args.seed)
        rows.append((f"{name} (env)", summarise(run), total_reward))
    env.close()

    world = ContentionWorld(ContentionConfig(seed=args.seed, **settings))
    for method in FIXED_METHODS:
        run = run_policy(world, make_baseline(method, world.n_servers, np.random.default_rng(args.seed)))
        rows.append((method, summarise(run), float("nan")))

    print(f"UC{args.uc}, {args.users} users, load {args.load:g}, {args.requests} requests, seed {args.seed}")
    print(f"{'method':<22}" + "".join(f"{column:>17}" for column in COLUMNS) + f"{'Eq. 5 total':>14}")
    for name, row, total_reward in rows:
        print(f"{name:<22}" + "".join(f"{float(row[column]):>17.3f}" for column in COLUMNS)
              + f"{total_reward:>14.2f}")


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad setting: one line on stderr and exit code 2
