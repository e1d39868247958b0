"""``run.json``: what a results folder records about its run (docs/results.md), written
deterministically and read back with checks."""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from yafs_safetail.results.files import (
    RUN_FILE,
    ResultsFileError,
    _one_line,
    _results_file,
    write_text_atomic,
)

#: ``run.json`` key of a run whose learning rate was set instead of the preset's
#: (``--learning-rate``); absent when the preset's own rate was used.
LEARNING_RATE_OVERRIDE_KEY = "learning_rate_override"
#: ``run.json`` key of the world settings a run's own options changed from its preset's world
#: (``--target-latency-s``, ``--load-peak-users``, ``--target-compute``: name -> value); absent
#: when none did. The ``world`` key holds the settings after them.
WORLD_OVERRIDES_KEY = "world_overrides"
#: ``run.json`` key of the placement file used (beside ``topology``); absent in runs written
#: before it was recorded.
PLACEMENT_KEY = "placement"
#: ``run.json`` key of the traces folder a run read (``--traces``); absent when it read the packaged
#: ``traces/``, as every run before the option did.
TRACES_KEY = "traces"
#: ``run.json`` key of the result-changing options a run set away from their defaults, as options
#: (``["--failure-probability 0.2"]``); absent when none was.
CHANGED_SETTINGS_KEY = "changed_settings"


@dataclass(slots=True)
class RunMetadata:
    """What ``run.json`` records about a run.

    Attributes:
        use_case: 1, 2 or 3.
        use_case_name: e.g. "object detection (YOLOv5)".
        preset: "paper" or "tuned".
        seed: the run's seed.
        n_servers: n, the number of edge servers.
        beta: β, the number of steps averaged per point of the per-episode plots.
        train_steps: SafeTail's training steps.
        test_steps: test steps per method.
        topology: the topology file used.
        methods: every method in the run.
        package_version: ``yafs_safetail.__version__``.
        command: the command line that produced the run.
        extra: any further keys, kept as they are.
    """

    use_case: int
    use_case_name: str
    preset: str
    seed: int
    n_servers: int
    beta: int
    train_steps: int
    test_steps: int
    topology: str
    methods: list[str]
    package_version: str
    command: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def learning_rate_note(self) -> str:
        """What to write after the preset's name: empty, or ``, learning rate 0.001
        (--learning-rate)`` for a run whose learning rate was not the preset's."""
        rate = self.extra.get(LEARNING_RATE_OVERRIDE_KEY)
        return "" if rate is None else f", learning rate {rate:g} (--learning-rate)"

    @property
    def settings_note(self) -> str:
        """What titles add after the seed: empty, or ``; --failure-probability 0.2`` for a run
        that set options beyond use case, preset and seed."""
        changed = self.extra.get(CHANGED_SETTINGS_KEY) or []
        return "" if not changed else "; " + ", ".join(map(str, changed))

    @property
    def baseline_reading(self) -> str | None:
        """How this run's MinLoad-x and MinProp-x chose (``world.baseline_reading``): None in a
        run written before the reading was recorded, which read the paper's text."""
        world = self.extra.get("world")
        return world.get("baseline_reading") if isinstance(world, dict) else None

    def to_json(self) -> str:
        """Deterministic JSON text (sorted keys, two-space indent, trailing newline)."""
        data = {k: v for k, v in asdict(self).items() if k != "extra"}
        data.update(self.extra)
        return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


RUN_JSON_KEYS: tuple[str, ...] = tuple(f.name for f in fields(RunMetadata) if f.name != "extra")
_RUN_INT_KEYS = ("use_case", "seed", "n_servers", "beta", "train_steps", "test_steps")


def write_run_json(directory: str | os.PathLike[str], run: RunMetadata) -> Path:
    """Write ``run.json`` into ``directory`` atomically and deterministically."""
    return write_text_atomic(Path(directory) / RUN_FILE, run.to_json())


def read_run_json(path: str | os.PathLike[str]) -> RunMetadata:
    """Read and check ``run.json`` (or the one inside a results folder).

    Raises:
        ResultsFileError: missing file, bad JSON, a missing key or a value of the wrong type.
    """
    file = _results_file(path, RUN_FILE)
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ResultsFileError(f"{file}: not valid JSON: {_one_line(error)}") from None
    if not isinstance(data, dict):
        raise ResultsFileError(f"{file}: expected a JSON object at the top level")
    missing = [k for k in RUN_JSON_KEYS if k not in data]
    if missing:
        raise ResultsFileError(f"{file}: missing key(s) {', '.join(missing)}")
    for key in _RUN_INT_KEYS:
        if not isinstance(data[key], int) or isinstance(data[key], bool):
            raise ResultsFileError(f"{file}: key {key}: expected an integer, got {data[key]!r}")
    if data["beta"] < 1:
        raise ResultsFileError(f"{file}: key beta: expected an integer >= 1, got {data['beta']!r}")
    if not isinstance(data["methods"], list) or not all(isinstance(m, str) for m in data["methods"]):
        raise ResultsFileError(f"{file}: key methods: expected a list of method names")
    known = {k: data[k] for k in RUN_JSON_KEYS}
    for key in ("use_case_name", "preset", "topology", "package_version", "command"):
        known[key] = str(known[key])
    extra = {k: v for k, v in data.items() if k not in known}
    return RunMetadata(**known, extra=extra)
