"""Train a Stable-Baselines3 agent on SafeTail's decision problem and compare it with SafeTail.

The agent (DQN or PPO) learns through the Gymnasium environment ``yafs_safetail/SafeTail-v0``:
one step is one request, the action is the subset of edge servers it goes to, the observation
is SafeTail's own scaled state vector, the reward is Eq. 5. It trains on the training world of
``run_usecase.py --seed S`` and is then tested greedily on that run's test world, so it sees
exactly the requests SafeTail and the baselines are tested on. SafeTail itself is trained and
tested here by ``run_experiment`` with the same seed and step budget.

    pip install -e '.[rl]'                                    # Stable-Baselines3 and PyTorch (CPU)
    python examples/sb3_agent.py --uc 1 --algo dqn            # UC1: 10,000 training requests
    python examples/sb3_agent.py --uc 1 --algo ppo --seed 3 --out results/uc1-ppo-s3
    python examples/sb3_agent.py --uc 1 --steps-scale 0.02 --timesteps 300   # a quick look

The table gives the test phase's latency percentiles (numpy's linear interpolation, as
summary.csv), the mean number of servers per request and the share of requests that met their
target τ. ``--out`` keeps SafeTail's results folder (summary.csv, requests.csv, run.json,
policy.keras) and adds the agent's model and test rows to it.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import gymnasium
import pandas as pd

import yafs_safetail
from yafs_safetail import results
from yafs_safetail.cli import run_cli
from yafs_safetail.methods.registry import ORACLE, SAFETAIL
from yafs_safetail.record import RequestRecord, records_frame
from yafs_safetail.runs.experiment import ExperimentConfig, run_experiment

try:
    import torch
    from stable_baselines3 import DQN, PPO
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.utils import set_random_seed
except ImportError as missing:  # the rl extra is optional: say how to get it, no traceback
    print(f"sb3_agent.py needs Stable-Baselines3 and PyTorch ({missing.name} is missing): "
          "pip install -e '.[rl]'", file=sys.stderr)
    sys.exit(2)

PRESET = "paper"  # the preset run_usecase.py uses by default: its world, δ, α_s and step budget
REFERENCES = (ORACLE, "MinLoad-3", "MinProp-1")  # for scale: the per-request bound, two heuristics


@dataclass(frozen=True)
class Config:
    """One run. The command line sets the first six; the rest are the agents' settings."""

    uc: int = 1
    seed: int = 0
    steps_scale: float = 1.0
    algo: str = "dqn"
    timesteps: int | None = None  # None: SafeTail's training budget (the training world's requests)
    out: Path | None = None
    # Each request's reward depends on that request's subset only (SafeTail learns it as a
    # contextual bandit, without bootstrapping), so the agents do not discount a future either.
    gamma: float = 0.0
    # SafeTail's network (presets.DEFAULT_HIDDEN_WIDTHS), so the two differ in how they learn,
    # not in what they can represent.
    hidden_widths: tuple[int, ...] = (128, 128, 128, 64, 64)
    batch_size: int = 64
    # DQN: ε falls from 1 to 0.05 over the first half of training (SafeTail's paper preset
    # explores until the end of its budget; a greedy second half lets DQN settle).
    dqn_exploration_fraction: float = 0.5
    dqn_learning_starts: int = 256  # one episode (α_s) of random subsets before the first update
    dqn_learning_rate: float = 1e-3
    # PPO: one rollout per episode (α_s = 256 requests), ten passes over it.
    ppo_rollout_steps: int = 256
    ppo_learning_rate: float = 3e-4
    ppo_epochs: int = 10
    ppo_entropy_coef: float = 0.01  # 31 subsets: keeps PPO from collapsing on one too early


def parse_args(argv: Sequence[str] | None) -> Config:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uc", type=int, default=1, choices=(1, 2, 3), help="use case (default 1)")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed, as run_usecase.py --seed")
    parser.add_argument("--steps-scale", type=float, default=1.0,
                        help="fraction of the preset's training and test requests (default 1)")
    parser.add_argument("--algo", choices=("dqn", "ppo"), default="dqn")
    parser.add_argument("--timesteps", type=int, default=None,
                        help="the agent's training requests (default: SafeTail's training budget)")
    parser.add_argument("--out", type=Path, default=None,
                        help="keep SafeTail's results folder here, with the agent's model and rows")
    args = parser.parse_args(argv)
    if args.seed < 0 or not args.steps_scale > 0 or (args.timesteps is not None and args.timesteps < 1):
        parser.error("--seed must be >= 0, --steps-scale > 0 and --timesteps >= 1")
    return Config(uc=args.uc, seed=args.seed, steps_scale=args.steps_scale, algo=args.algo,
                  timesteps=args.timesteps, out=args.out)


def make_env(config: Config, phase: str, method_name: str) -> gymnasium.Env:
    """The environment of one phase: the world ``run_usecase.py`` draws for it, seeded on reset."""
    return gymnasium.make(yafs_safetail.ENV_ID, use_case=config.uc, preset=PRESET, phase=phase,
                          steps_scale=config.steps_scale, observation="vector", method_name=method_name)


def make_agent(config: Config, env: gymnasium.Env) -> BaseAlgorithm:
    """A DQN or PPO agent on CPU. ``seed`` makes SB3 seed its generators and the environment's
    first reset, so training starts on the training world of ``run_usecase.py --seed``."""
    if config.algo == "dqn":
        # One update per request (SafeTail's paper preset makes one per two); with γ = 0 the
        # target network never enters the loss, so how often it is copied does not matter.
        return DQN("MlpPolicy", env, learning_rate=config.dqn_learning_rate, gamma=config.gamma,
                   batch_size=config.batch_size, learning_starts=config.dqn_learning_starts,
                   train_freq=1, gradient_steps=1,
                   exploration_fraction=config.dqn_exploration_fraction, exploration_final_eps=0.05,
                   policy_kwargs={"net_arch": list(config.hidden_widths)}, seed=config.seed, device="cpu",
                   verbose=0)
    widths = list(config.hidden_widths)
    return PPO("MlpPolicy", env, learning_rate=config.ppo_learning_rate, gamma=config.gamma,
               n_steps=config.ppo_rollout_steps, batch_size=config.batch_size, n_epochs=config.ppo_epochs,
               ent_coef=config.ppo_entropy_coef, policy_kwargs={"net_arch": {"pi": widths, "vf": widths}},
               seed=config.seed, device="cpu", verbose=0)


def evaluate_greedily(agent: BaseAlgorithm, env: gymnasium.Env, seed: int) -> list[RequestRecord]:
    """The agent's records on every request of the test world, its best subset each time."""
    observation, _ = env.reset(seed=seed)  # the test world of run_usecase.py --seed
    n_requests = env.unwrapped.n_steps
    records: list[RequestRecord] = []
    for done in range(1, n_requests + 1):
        action, _ = agent.predict(observation, deterministic=True)
        observation, _, _, truncated, info = env.step(int(action))
        records.append(info["record"])
        if truncated and done < n_requests:  # an episode (α_s requests) ended: go on in the same world
            observation, _ = env.reset()
    return records


def print_table(summary: pd.DataFrame) -> None:
    print(f"{'method':<12} {'p50_s':>7} {'p90_s':>7} {'p95_s':>7} {'p99_s':>7} {'servers':>7} {'met_target':>10}")
    for row in summary.itertuples():
        print(f"{row.method:<12} {row.p50_s:7.3f} {row.p90_s:7.3f} {row.p95_s:7.3f} {row.p99_s:7.3f} "
              f"{row.mean_n_selected:7.2f} {row.target_met_rate:10.3f}")


def main(argv: Sequence[str] | None = None) -> int:
    config = parse_args(argv)
    agent_name = f"SB3-{config.algo.upper()}"

    # Determinism on CPU, as SB3 recommends: seed Python's, numpy's and torch's generators (SB3
    # draws its exploration and minibatches from numpy's global one, so it has to be seeded, not
    # avoided), refuse nondeterministic kernels, and use one thread so that sums are added in
    # the same order on any machine (a network this small gains nothing from threads anyway).
    set_random_seed(config.seed, using_cuda=False)
    torch.use_deterministic_algorithms(True)
    torch.set_num_threads(1)

    # 1. SafeTail, trained and tested as run_usecase.py does (the baselines come with it: they
    #    are tested on the same requests, and three of them are printed for scale).
    started_s = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="sb3_agent-") as scratch:
        out_dir = config.out or Path(scratch) / "safetail"
        report = run_experiment(ExperimentConfig(
            use_case=config.uc, preset=PRESET, seed=config.seed, out_dir=out_dir,
            steps_scale=config.steps_scale, write_yafs_csv=False, figures=False, progress=False,
            command=" ".join(["python", "examples/sb3_agent.py", *(sys.argv[1:] if argv is None else argv)]),
        ))
    safetail_s = time.perf_counter() - started_s

    # 2. The agent, trained on the same training world with the same number of requests.
    started_s = time.perf_counter()
    train_env = make_env(config, "train", agent_name)
    timesteps = config.timesteps or train_env.unwrapped.n_steps
    agent = make_agent(config, train_env)
    agent.learn(total_timesteps=timesteps)
    train_s = time.perf_counter() - started_s

    # 3. The agent tested greedily on the same test requests as SafeTail and the baselines.
    started_s = time.perf_counter()
    test_env = make_env(config, "test", agent_name)
    records = evaluate_greedily(agent, test_env, config.seed)
    rows = records_frame(records, "test", test_env.unwrapped.episode_steps)
    test_s = time.perf_counter() - started_s
    if config.out is not None:
        agent.save(config.out / f"{agent_name}.zip")
        rows.to_csv(config.out / f"{agent_name}_test.csv", index=False)

    # 4. One table, every row computed by the same code as summary.csv.
    agent_summary = results.summarize(rows)
    others = report.summary[report.summary["method"].isin([SAFETAIL, *REFERENCES])]
    print(f"UC{config.uc}, seed {config.seed}, {PRESET} preset, steps scale {config.steps_scale:g}: "
          f"{agent_name} trained on {timesteps} requests, SafeTail on {train_env.unwrapped.n_steps}; "
          f"{len(records)} test requests each")
    print_table(pd.concat([agent_summary, others], ignore_index=True))
    print(f"wall time: SafeTail and baselines {safetail_s:.0f} s, {agent_name} training {train_s:.0f} s, "
          f"test {test_s:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))  # a bad setting or budget: one line on stderr and exit code 2
