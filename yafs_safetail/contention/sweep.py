"""The load sweep: every method at every offered load, in the contention world.

For each load: a training world and a test world (independent streams, same users and
settings); SafeTail learns on the training world at that load (its preset's learner, one
training round every κ requests, Eq. 5 against τ) and is tested greedily; every other method
runs on the test world only. All methods of a load see the same arrivals and per-request draws
(common random numbers). One row per (load, method) goes to ``sweep.csv``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from yafs_safetail.cli import load_list
from yafs_safetail.contention.run import SUMMARY_COLUMNS, TARGETS, run_policy, summarise
from yafs_safetail.contention.world import ContentionConfig, ContentionError, ContentionWorld
from yafs_safetail.logs import RUN_LOG_FILE, Phase, run_log
from yafs_safetail.methods.policy import Policy
from yafs_safetail.methods.registry import SAFETAIL, make_baseline
from yafs_safetail.methods.safetail.policy import SAFETAIL_DISPATCH, SafeTailPolicy
from yafs_safetail.methods.safetail.presets import (
    OBJECTIVES,
    PRESET_NAMES,
    get_preset,
    scaled_steps,
)
from yafs_safetail.results.files import write_text_atomic
from yafs_safetail.runs.config import (
    BOOLEAN,
    POSITIVE_INTEGER,
    POSITIVE_NUMBER,
    Check,
    one_of,
    setting,
)
from yafs_safetail.runs.grid import ID_LENGTH, RunSpec, code_version, file_identity
from yafs_safetail.runs.output import StagedOutput
from yafs_safetail.runs.workers import method_rng

log = logging.getLogger(__name__)

#: Every fixed method of the sweep (SafeTail is added unless left out).
DEFAULT_SWEEP_METHODS: tuple[str, ...] = (
    "Oracle", "Rand-1", "Rand-2", "MinLoad-1", "MinLoad-2", "MinProp-1", "MinProp-2", "Hedge", "Tied",
)
#: How many networks the value learner averages unless told (``SweepConfig.value_networks``):
#: chosen on seeds 0-6 over one network, then judged on seeds 19-30 (docs/deviations.md D13).
DEFAULT_VALUE_NETWORKS = 3
#: Test requests per load at steps scale 1.
TEST_REQUESTS = 20_000
#: sweep.csv's columns, in order.
#: (No wall times: the same seed must give the same file.)
SWEEP_COLUMNS: tuple[str, ...] = ("load", "offered_load", *SUMMARY_COLUMNS, "train_requests")


def _method_names(text: str) -> tuple[str, ...]:
    """``--methods``: comma-separated method names (checked when the sweep builds them)."""
    return tuple(name.strip() for name in text.split(",") if name.strip())


#: The methods a sweep may be given (any baseline name; checked when the policies are built).
METHOD_NAMES = Check("comma-separated method names",
                     lambda v: isinstance(v, tuple) and all(isinstance(m, str) for m in v), _method_names)
#: Offered loads: distinct utilisations in (0, 10).
LOADS = Check("distinct loads in (0, 10)", lambda v: isinstance(v, tuple) and len(set(v)) == len(v) and all(
    not isinstance(x, bool) and isinstance(x, float | int) and 0 < x < 10 for x in v), load_list)


@dataclass(frozen=True)
class SweepConfig:
    """A load sweep: the contention world of every load (``base``; its ``load``, ``phase`` and
    ``n_requests`` are set per load and phase) and the sweep's own settings, each declared once
    with its help (``runs.config.setting``; ``experiments/load_sweep.py`` derives its options
    from them). The value learner (``learner="value"``) has its own reward (``"latency-cost"``),
    so ``reward`` stays ``"paper"`` with it (docs/deviations.md D13)."""

    base: ContentionConfig
    loads: tuple[float, ...] = setting((0.1, 0.3, 0.5, 0.7, 0.9),
                                       "offered loads, comma-separated (default 0.1,0.3,0.5,0.7,0.9)",
                                       check=LOADS)
    methods: tuple[str, ...] = setting(DEFAULT_SWEEP_METHODS, "fixed methods, comma-separated (default: all)",
                                       check=METHOD_NAMES)
    safetail: bool = setting(True, "fixed methods only", check=BOOLEAN, flag="--no-safetail",
                             action="store_false")
    preset: str = setting("paper", "SafeTail's preset (default paper)", check=one_of(PRESET_NAMES))
    steps_scale: float = setting(1.0, "scales SafeTail's training requests and the 20,000 test requests per load",
                                 check=POSITIVE_NUMBER)
    reward: str = setting("paper", "SafeTail's reward: Eq. 5 (default) or Eq. 5 without case 3's free miss "
                          "with all servers (docs/contention.md)", check=one_of(("paper", "no-free-miss")))
    target: str = setting("eq4", "the target τ of SafeTail's reward: eq4 (Eq. 4, the paper) or "
                          "observed-load (its compute term at the servers' load seen at dispatch; "
                          "docs/deviations.md D12)", check=one_of(TARGETS))
    learner: str = setting("target-vector", "SafeTail's training objective: target-vector (§III, default) or "
                           "value (the same network predicting each action's latency, its copies priced at "
                           "dispatch; docs/deviations.md D13)", check=one_of(OBJECTIVES))
    dispatch: str = setting("all", "how SafeTail's subset is sent: all at once (default, the paper) or tied "
                            "(cancelled once one copy starts running, as Tied; with --learner value, "
                            "at least two copies)", check=one_of(SAFETAIL_DISPATCH), flag="--safetail-dispatch")
    test_requests_per_load: int | None = setting(
        None, "test requests per load (default 20,000 × --steps-scale): more decide each p99 more closely",
        check=POSITIVE_INTEGER, flag="--test-requests", optional=True)
    value_networks: int | None = setting(
        None, "with --learner value: how many networks' predictions SafeTail averages "
        f"(default {DEFAULT_VALUE_NETWORKS}; docs/deviations.md D13)", check=POSITIVE_INTEGER, optional=True)

    def __post_init__(self) -> None:
        n_test = self.test_requests_per_load
        if n_test is not None and (isinstance(n_test, bool) or not isinstance(n_test, int) or n_test < 1):
            raise ContentionError(f"test requests per load must be an integer >= 1, got {n_test!r}")
        if self.learner not in OBJECTIVES:
            raise ContentionError(f"learner {self.learner!r}: expected one of {', '.join(OBJECTIVES)}")
        if self.dispatch not in SAFETAIL_DISPATCH:
            raise ContentionError(f"dispatch {self.dispatch!r}: expected one of {', '.join(SAFETAIL_DISPATCH)}")
        n_networks = self.n_value_networks
        if isinstance(n_networks, bool) or not isinstance(n_networks, int) or n_networks < 1:
            raise ContentionError(f"value networks must be an integer >= 1, got {n_networks!r}")
        if n_networks > 1 and self.learner != "value":
            raise ContentionError(f"{n_networks} value networks: only the value learner averages networks")
        if self.learner == "value" and self.reward != "paper":
            raise ContentionError(f"reward {self.reward!r}: the value learner has its own reward "
                                  "(latency-cost); leave the reward at paper")

    @property
    def n_value_networks(self) -> int:
        """The networks SafeTail's learner averages (``value_networks`` resolved)."""
        if self.value_networks is not None:
            return self.value_networks
        return DEFAULT_VALUE_NETWORKS if self.learner == "value" else 1

    @property
    def safetail_reward(self) -> str:
        """The reward SafeTail is trained with (the value learner's own, or ``reward``)."""
        return "latency-cost" if self.learner == "value" else self.reward

    @property
    def test_requests(self) -> int:
        if self.test_requests_per_load is not None:
            return self.test_requests_per_load
        return scaled_steps(TEST_REQUESTS, self.steps_scale)

    @property
    def train_requests(self) -> int:
        return scaled_steps(get_preset(self.preset, self.base.use_case).train_steps, self.steps_scale)


def _safetail_policy(world: ContentionWorld, preset: str, seed: int, train_steps: int,
                     reward: str = "paper", objective: str = "target-vector",
                     dispatch: str = "all", n_networks: int = 1) -> SafeTailPolicy:
    # Imported here: the learner brings TensorFlow, which a sweep without SafeTail never needs.
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.spaces import StateScales, state_dim

    use_case = world.use_case
    config = replace(get_preset(preset, use_case.number, train_steps=train_steps), objective=objective,
                     n_networks=n_networks)
    learner = SafeTailLearner(
        world.n_servers,
        state_dim(world.n_servers, len(use_case.gamma_columns), len(world.scenario.user_location)),
        config, seed, metadata={"use_case": use_case.number, "world": "contention"})
    return SafeTailPolicy(world.n_servers, method_rng(seed, SAFETAIL), learner=learner,
                          scales=StateScales.for_use_case(use_case.number), training=True,
                          reward_name=reward, dispatch=dispatch)


def run_sweep(config: SweepConfig, log: Callable[[str], None] = lambda line: None) -> pd.DataFrame:
    """Every (load, method) row of ``sweep.csv``, loads ascending, methods in the given order."""
    rows: list[dict[str, Any]] = []
    inputs = scenario = None
    for load in config.loads:
        test_config = replace(config.base, load=load, rate_per_user_hz=None, phase="test",
                              n_requests=config.test_requests)
        test_world = ContentionWorld(test_config, inputs, scenario)
        inputs, scenario = test_world.inputs, test_world.scenario
        policies: list[tuple[Policy, int]] = []
        if config.safetail:
            train_world = ContentionWorld(replace(test_config, phase="train", n_requests=config.train_requests),
                                          inputs, scenario)
            safetail = _safetail_policy(train_world, config.preset, config.base.seed, config.train_requests,
                                        config.safetail_reward, config.learner, config.dispatch,
                                        config.n_value_networks)
            trained = run_policy(train_world, safetail, target=config.target)
            log(f"load {load:g}: SafeTail trained on {config.train_requests} requests in {trained.wall_s:.1f} s")
            safetail.training = False
            policies.append((safetail, config.train_requests))
        for name in config.methods:
            policies.append((make_baseline(name, test_world.n_servers, method_rng(config.base.seed, name)), 0))
        for policy, train_requests in policies:
            run = run_policy(test_world, policy, target=config.target)
            row = {"load": load, "offered_load": test_world.offered_load(), **summarise(run),
                   "train_requests": train_requests}
            rows.append(row)
            log(f"load {load:g}: {policy.name:<10} p50 {row['p50_s']:.3f} s  p99 {row['p99_s']:.3f} s  "
                f"copies {row['mean_n_selected']:.2f}  fallback {row['fallback_rate']:.3f}  ({run.wall_s:.1f} s)")
    return pd.DataFrame(rows, columns=list(SWEEP_COLUMNS))


LOAD_POINT = "load_point"


def point_settings(config: SweepConfig, load: float) -> dict[str, Any]:
    """One load of the sweep as a campaign run's settings (JSON values, paths absolute)."""
    base = config.base
    conditions = base.user_conditions
    if conditions not in ("topology", "generated"):
        conditions = str(Path(conditions).resolve())
    return {
        "use_case": base.use_case, "users": base.users, "load": load, "seed": base.seed,
        "queue": base.queue, "cancel": base.cancel, "background": base.background, "world": base.world,
        "links": base.links,
        "topology": str(Path(base.topology).resolve()), "placement": str(Path(base.placement).resolve()),
        "user_conditions": conditions, "methods": list(config.methods), "safetail": config.safetail,
        "preset": config.preset, "steps_scale": config.steps_scale, "reward": config.reward,
        "target": config.target, "learner": config.learner, "dispatch": config.dispatch,
        "test_requests": config.test_requests, "value_networks": config.n_value_networks,
    }


def point_run_id(settings: Mapping[str, Any]) -> str:
    """The short hash of everything a load point's rows depend on (its settings, the input
    files' contents, the code version)."""
    identity = dict(settings, kind=LOAD_POINT, code_version=code_version())
    for key in ("topology", "placement"):
        identity[key] = file_identity(Path(settings[key]))
    if settings["user_conditions"] not in ("topology", "generated"):
        identity["user_conditions"] = file_identity(Path(settings["user_conditions"]))
    canonical = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:ID_LENGTH]


def load_point_specs(config: SweepConfig) -> list[RunSpec]:
    """One campaign run per load, in load order (folder ``load-<load>``)."""
    specs = []
    for load in config.loads:
        settings = point_settings(config, load)
        specs.append(RunSpec(name=f"load-{load:g}", run_id=point_run_id(settings), settings=settings,
                             kind=LOAD_POINT))
    return specs


def _point_config(settings: Mapping[str, Any]) -> SweepConfig:
    base = ContentionConfig(
        use_case=settings["use_case"], users=settings["users"], seed=settings["seed"],
        queue=settings["queue"], cancel=settings["cancel"], background=settings["background"],
        # Absent from the folders of earlier versions, whose links were read at the start.
        links=settings.get("links", "at-start"), world=settings["world"], topology=Path(settings["topology"]), placement=Path(settings["placement"]),
        user_conditions=settings["user_conditions"])
    return SweepConfig(base=base, loads=(float(settings["load"]),), methods=tuple(settings["methods"]),
                       safetail=settings["safetail"], preset=settings["preset"],
                       steps_scale=settings["steps_scale"], reward=settings["reward"],
                       target=settings["target"], learner=settings["learner"],
                       dispatch=settings["dispatch"],
                       # Absent from the folders of earlier versions, where it followed steps_scale.
                       test_requests_per_load=settings.get("test_requests"),
                       value_networks=settings.get("value_networks", 1))


def run_load_point(spec: RunSpec, out_dir: Path, command: str = "", overwrite: bool = False) -> Path:
    """Run one load of a sweep (a campaign run) into ``out_dir``: its ``sweep.csv`` rows, a
    ``run.json`` recording the run id and a ``run.log`` (staged; nothing is lost if it stops half
    way)."""
    from yafs_safetail import __version__

    output = StagedOutput(out_dir, overwrite)
    with output as staging:
        with run_log(staging / RUN_LOG_FILE):
            log.info("yafs-safetail %s: %s", __version__, command or "(run from Python)")
            log.info("load point %s (run id %s): %s", spec.name, spec.run_id,
                     ", ".join(f"{key}={value}" for key, value in spec.settings.items()))
            with Phase(f"{spec.name} sweep", logger=log):
                frame = run_sweep(_point_config(spec.settings), log=log.info)
            frame.to_csv(staging / "sweep.csv", index=False, float_format="%.6g")
            write_text_atomic(staging / "run.json", json.dumps({
                "package_version": __version__, "campaign_run_id": spec.run_id, "kind": LOAD_POINT,
                "command": command, "settings": dict(spec.settings)}, indent=1, sort_keys=True) + "\n")
        output.publish()
    return out_dir


def best_fixed_p99(frame: pd.DataFrame, load: float) -> tuple[str, float]:
    """The fixed method (not SafeTail) with the lowest p99 at ``load``."""
    rows = frame[(frame["load"] == load) & (frame["method"] != SAFETAIL)]
    best = rows.loc[rows["p99_s"].idxmin()]
    return str(best["method"]), float(best["p99_s"])


def sweep_checks(frame: pd.DataFrame) -> list[tuple[str, bool, str]]:
    """The sweep's goals, each as (claim, holds, measured) — computed, never asserted."""
    loads = sorted(frame["load"].unique())
    checks: list[tuple[str, bool, str]] = []

    def p99(method: str, load: float) -> float:
        values = frame[(frame["method"] == method) & (frame["load"] == load)]["p99_s"]
        return float(values.iloc[0]) if len(values) else math.nan

    if "Oracle" in set(frame["method"]) and len(loads) > 1:
        low, high = loads[0], loads[-1]
        ratio = p99("Oracle", high) / p99("Oracle", low)
        checks.append((f"Oracle p99 at load {high:g} >= 1.5x at load {low:g}", ratio >= 1.5, f"{ratio:.2f}x"))
        singles = [m for m in frame["method"].unique() if m.endswith("-1")]
        if singles:  # (without a single-dispatch method in the sweep there is nothing to compare)
            worse_at = [load for load in loads if p99("Oracle", load) > min(p99(m, load) for m in singles)]
            checks.append(("Oracle worse than single dispatch beyond some load", bool(worse_at),
                           f"from load {worse_at[0]:g}" if worse_at else "never"))
    if SAFETAIL in set(frame["method"]):
        if len(loads) > 1:  # (one load says nothing of how the copies follow the load)
            copies = [float(frame[(frame["method"] == SAFETAIL) & (frame["load"] == load)]["mean_n_selected"].iloc[0])
                      for load in loads]
            checks.append(("SafeTail: fewer copies as load rises", copies[-1] < copies[0],
                           " -> ".join(f"{c:.2f}" for c in copies)))
        for load in loads:
            method, best = best_fixed_p99(frame, load)
            ours = p99(SAFETAIL, load)
            checks.append((f"SafeTail p99 <= 1.05x best fixed at load {load:g}", ours <= 1.05 * best,
                           f"{ours:.3f} s vs {method} {best:.3f} s ({ours / best:.2f}x)"))
            if load >= 0.7 and "Oracle" in set(frame["method"]):
                checks.append((f"SafeTail p99 < Oracle's at load {load:g}", ours < p99("Oracle", load),
                               f"{ours:.3f} s vs {p99('Oracle', load):.3f} s"))
    return checks


def seeds_markdown(frames: Mapping[int, pd.DataFrame]) -> str:
    """Several seeds' sweeps (``{seed: sweep.csv's frame}``) side by side: per seed and load,
    SafeTail's p99 over the best fixed method's and SafeTail's copies per request (when SafeTail
    ran), then each goal of :func:`sweep_checks` with the seeds where it holds."""
    seeds = sorted(frames)
    lines: list[str] = []
    if all(SAFETAIL in set(frame["method"]) for frame in frames.values()):
        loads = sorted(frames[seeds[0]]["load"].unique())
        lines += ["Each cell: SafeTail's p99 over the best fixed method's (that method), then SafeTail's "
                  "copies per request.", "",
                  "| seed | " + " | ".join(f"{load:g}" for load in loads) + " |",
                  "|---|" + "---|" * len(loads)]
        ratios: dict[float, list[float]] = {load: [] for load in loads}
        for seed in seeds:
            frame = frames[seed]
            cells = []
            for load in loads:
                method, best = best_fixed_p99(frame, load)
                ours = frame[(frame["method"] == SAFETAIL) & (frame["load"] == load)].iloc[0]
                ratios[load].append(float(ours["p99_s"]) / best)
                cells.append(f"{ratios[load][-1]:.2f} ({method}), {ours['mean_n_selected']:.2f}")
            lines.append(f"| {seed} | " + " | ".join(cells) + " |")
        lines.append("| median (min–max) | " + " | ".join(
            f"{np.median(r):.2f} ({min(r):.2f}–{max(r):.2f})" for r in ratios.values()) + " |")
        lines.append("")
    holds: dict[str, list[int]] = {}
    for seed in seeds:
        for claim, ok, _ in sweep_checks(frames[seed]):
            holds.setdefault(claim, [])
            if ok:
                holds[claim].append(seed)
    lines += ["| goal | holds in | seeds where it holds |", "|---|---|---|"]
    lines += [f"| {claim} | {len(ok)} of {len(seeds)} | {', '.join(map(str, ok)) or 'none'} |"
              for claim, ok in holds.items()]
    return "\n".join(lines) + "\n"


def plot_sweep(frame: pd.DataFrame, out_dir: Path) -> list[Path]:
    """sweep_latency.png (p50 and p99 against load, per method) and sweep_copies.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    methods = list(dict.fromkeys(frame["method"]))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharex=True)
    for axis, column, title in ((axes[0], "p50_s", "median"), (axes[1], "p99_s", "p99")):
        for method in methods:
            rows = frame[frame["method"] == method]
            axis.plot(rows["load"], rows[column], marker="o", label=method,
                      linewidth=2.5 if method == SAFETAIL else 1.2)
        axis.set_yscale("log")
        axis.set_xlabel("offered load")
        axis.set_ylabel(f"{title} latency (s)")
        axis.set_title(f"{title} latency against load")
        axis.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    written.append(out_dir / "sweep_latency.png")
    fig.savefig(written[-1], dpi=120, metadata={"Software": None})
    plt.close(fig)
    fig, axis = plt.subplots(figsize=(5.5, 4.2))
    for method in methods:
        rows = frame[frame["method"] == method]
        axis.plot(rows["load"], rows["mean_n_selected"], marker="o", label=method,
                  linewidth=2.5 if method == SAFETAIL else 1.2)
    axis.set_xlabel("offered load")
    axis.set_ylabel("copies per request")
    axis.set_title("copies per request against load")
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    written.append(out_dir / "sweep_copies.png")
    fig.savefig(written[-1], dpi=120, metadata={"Software": None})
    plt.close(fig)
    return written


def checks_markdown(frame: pd.DataFrame) -> str:
    """The goals of :func:`sweep_checks` as a Markdown table."""
    lines = ["| goal | holds | measured |", "|---|---|---|"]
    lines += [f"| {claim} | {'yes' if ok else 'no'} | {measured} |" for claim, ok, measured in sweep_checks(frame)]
    return "\n".join(lines) + "\n"


def markdown_table(frame: pd.DataFrame) -> str:
    """A Markdown table, floats to three decimals."""
    def cell(value: object) -> str:
        return f"{value:.3f}" if isinstance(value, float | np.floating) else str(value)

    lines = ["| " + " | ".join(frame.columns) + " |", "|" + "---|" * len(frame.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in frame.itertuples(index=False)]
    return "\n".join(lines)
