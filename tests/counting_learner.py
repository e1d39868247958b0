"""A user's learning policy, written only against the public protocol (``tests/test_learning_policy.py``
runs it with ``--method tests/counting_learner.py:CountingLearner``).

While training it sends each request to one server drawn at random and counts, per server, the
requests and the seconds they took; while testing it sends each request to the server with the
lowest mean latency it saw.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from yafs_safetail.methods.learning import LearningPolicy


class CountingLearner(LearningPolicy):
    observes = False  # it never reads ω^t

    def __init__(self, n_servers: int, rng: np.random.Generator) -> None:
        super().__init__(n_servers, rng)
        self.requests = np.zeros(n_servers, dtype=np.int64)
        self.latency_sum_s = np.zeros(n_servers)

    def choose(self, observation: object) -> list[int]:
        if self.training:
            return [int(self.rng.integers(self.n_servers))]
        mean_s = np.where(self.requests > 0, self.latency_sum_s / np.maximum(self.requests, 1), np.inf)
        return [int(np.argmin(mean_s))]

    def feedback(self, outcome):  # type: ignore[no-untyped-def]
        if self.training:
            self.requests[outcome.servers[0]] += 1
            self.latency_sum_s[outcome.servers[0]] += outcome.latency_s
        return None

    def end_training(self) -> str:
        return f"{int(self.requests.sum())} requests counted"

    def save(self, path: Path) -> None:
        path.write_text(json.dumps({"requests": self.requests.tolist(),
                                    "latency_sum_s": self.latency_sum_s.tolist()}))

    def load(self, path: Path) -> None:
        saved = json.loads(path.read_text())
        self.requests = np.array(saved["requests"], dtype=np.int64)
        self.latency_sum_s = np.array(saved["latency_sum_s"])

    def checkpoint_state(self) -> object:
        return {"requests": self.requests.copy(), "latency_sum_s": self.latency_sum_s.copy(),
                "rng": self.rng.bit_generator.state}

    def restore_checkpoint_state(self, state) -> None:  # type: ignore[no-untyped-def]
        self.requests = state["requests"].copy()
        self.latency_sum_s = state["latency_sum_s"].copy()
        self.rng.bit_generator.state = state["rng"]

    def run_json_fields(self) -> dict[str, object]:
        return {"counting_learner_requests": int(self.requests.sum())}
