"""What each SafeTail learns under contention, measured over its training (issue 33, item 2).

At each load, each SafeTail of a load sweep trains exactly as the sweep trains it (the same
world, seeds and requests: :func:`~yafs_safetail.runs.sweep.run_sweep`'s training step),
watched from outside: per training request, the copies it sent, the users active per server
when it chose (ours running or waiting, plus background tenants: the queue its copies join),
and the request's latency. The requests are cut into equal windows of training, and each
window's means go to ``mechanism.csv``; ``mechanism.png`` (``results.figures.mechanism``) draws
copies and queue length against training progress, one line per load, one column per SafeTail.

Watching changes nothing: the wrapper draws no random numbers and passes every choice and
record through, so the trained policy is the sweep's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from yafs_safetail.contention.run import run_policy
from yafs_safetail.contention.world import ContentionWorld
from yafs_safetail.methods.policy import Policy
from yafs_safetail.results.figures.mechanism import mechanism_figure as mechanism_figure
from yafs_safetail.runs.sweep import _safetail_policy as safetail_policy
from yafs_safetail.runs.sweep_config import SweepConfig

if TYPE_CHECKING:
    from yafs_safetail.edge.observation import Observation
    from yafs_safetail.record import RequestRecord

#: mechanism.csv's columns, in order.
MECHANISM_COLUMNS: tuple[str, ...] = (
    "method", "load", "window", "first_request", "requests", "mean_copies", "mean_active_per_server",
    "mean_latency_s", "p99_latency_s",
)
#: Windows of training per load unless told otherwise.
DEFAULT_WINDOWS = 20


class WatchedPolicy(Policy):
    """A policy passed through unchanged, noting the load it saw at each choice.

    Attributes:
        inner: the watched policy.
        active_per_server: per request in choice order, the mean users active per server.
    """

    def __init__(self, inner: Policy) -> None:
        super().__init__(inner.n_servers, inner.rng)
        self.inner = inner
        self.name = inner.name
        self.dispatch = inner.dispatch
        self.active_per_server: list[float] = []

    def choose(self, observation: Observation | None) -> Sequence[int]:
        assert observation is not None  # observes is True: the dispatcher always builds one
        self.active_per_server.append(float(np.mean(observation.server_active_users)))
        return self.inner.choose(observation)

    def feedback(self, outcome: RequestRecord) -> RequestRecord | None:
        return self.inner.feedback(outcome)


def window_rows(method: str, load: float, n_copies: np.ndarray, active_per_server: np.ndarray,
                latency_s: np.ndarray, windows: int) -> list[dict[str, float | int | str]]:
    """``mechanism.csv``'s rows of one training run: equal windows of requests in order
    (the last windows one request shorter when they do not divide evenly)."""
    rows: list[dict[str, float | int | str]] = []
    bounds = np.linspace(0, len(n_copies), min(windows, len(n_copies)) + 1).astype(int)
    for window, (start, stop) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        rows.append({
            "method": method, "load": load, "window": window, "first_request": int(start),
            "requests": int(stop - start),
            "mean_copies": float(np.mean(n_copies[start:stop])),
            "mean_active_per_server": float(np.mean(active_per_server[start:stop])),
            "mean_latency_s": float(np.mean(latency_s[start:stop])),
            "p99_latency_s": float(np.quantile(latency_s[start:stop], 0.99)),
        })
    return rows


def measure_training(config: SweepConfig, windows: int = DEFAULT_WINDOWS,
                     log: Callable[[str], None] = lambda line: None) -> pd.DataFrame:
    """Every SafeTail of ``config`` trained at every load as the sweep trains it, watched.

    Returns:
        ``mechanism.csv``'s rows: SafeTails in the sweep's order, loads ascending, windows in order.
    """
    rows: list[dict[str, float | int | str]] = []
    inputs = scenario = None
    for variant in config.safetails:
        for load in config.loads:
            world = ContentionWorld(replace(config.base, load=load, rate_per_user_hz=None, phase="train",
                                            n_requests=variant.train_requests), inputs, scenario)
            inputs, scenario = world.inputs, world.scenario
            watched = WatchedPolicy(safetail_policy(world, variant, config.base.seed))
            run = run_policy(world, watched, target=config.target)
            # Choices come in emission order, as the engine asks for them; the result is in it too.
            active = np.asarray(watched.active_per_server)
            rows += window_rows(variant.name, load, run.result.n_copies, active, run.result.latency_s, windows)
            last = rows[-1]
            log(f"{variant.name} at load {load:g}: {variant.train_requests} training requests; last window "
                f"{last['mean_copies']:.2f} copies, {last['mean_active_per_server']:.2f} active per server")
    return pd.DataFrame(rows, columns=list(MECHANISM_COLUMNS))
