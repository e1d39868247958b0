"""How many module boundaries one request crosses, from its emission to its requests.csv row.

Deploys a SafeTail simulation of the paper's scenario (use case 1, training mode, so the
request also goes through the reward and the learner's store), runs a first request to warm
the caches, then traces the second one with ``sys.setprofile``: its emission, the policy's
decision, the copies' hops and service, the first reply, the record, the policy's feedback,
and the record's way into the ``requests.csv`` rows and file. Every call from one module of the
package into another counts once per (caller module, callee module) pair; the YAFS core's
internal calls are left out (the core is a library the project uses). Prints each pair, then
``module_boundaries=<n>``.

    python benchmarks/bench_request_path.py
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
from pathlib import Path

import numpy as np

import yafs_safetail
from yafs_safetail.edge.calibration import world_settings
from yafs_safetail.edge.scenario import DEFAULT_PLACEMENT, DEFAULT_TOPOLOGY, load_scenario
from yafs_safetail.edge.usecases import get_use_case
from yafs_safetail.edge.world import build_world, load_inputs
from yafs_safetail.methods.safetail import SafeTailLearner, StateScales, state_dim
from yafs_safetail.methods.safetail.policy import SafeTailPolicy
from yafs_safetail.methods.safetail.presets import get_preset
from yafs_safetail.record import records_frame
from yafs_safetail.results import write_requests_csv
from yafs_safetail.sim.runner import deploy

PACKAGE = str(Path(yafs_safetail.__file__).resolve().parent) + "/"
CORE = PACKAGE + "yafs/"


def module_of(filename: str) -> str | None:
    return filename[len(PACKAGE):] if filename.startswith(PACKAGE) else None


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    use_case = get_use_case(1)
    scenario = load_scenario(DEFAULT_TOPOLOGY, DEFAULT_PLACEMENT)
    world = build_world(scenario, use_case, load_inputs(use_case), 4, seed=0, phase="train",
                        settings=world_settings("calibrated"))
    learner = SafeTailLearner(5, state_dim(5, 0, 2), get_preset("paper", 1), seed=0)
    policy = SafeTailPolicy(5, np.random.default_rng(0), learner=learner,
                            scales=StateScales.for_use_case(1), training=True)
    simulation = deploy(world, policy)
    simulation.run_until_request(1)  # warm-up: first request, caches, routes

    pairs: collections.Counter[tuple[str, str]] = collections.Counter()

    def profile(frame, event, arg):  # type: ignore[no-untyped-def]
        if event != "call":
            return
        callee = module_of(frame.f_code.co_filename)
        caller_frame = frame.f_back
        while caller_frame is not None and module_of(caller_frame.f_code.co_filename) is None:
            caller_frame = caller_frame.f_back
        if callee is None or caller_frame is None:
            return
        caller = module_of(caller_frame.f_code.co_filename)
        if caller != callee and not (caller.startswith("yafs/") and callee.startswith("yafs/")):
            pairs[(caller, callee)] += 1

    def one_request_to_its_row() -> None:
        simulation.run_until_request(2)
        with tempfile.TemporaryDirectory() as folder:
            write_requests_csv(records_frame(simulation.records[1:], "train", 256), folder)

    sys.setprofile(profile)
    try:
        one_request_to_its_row()
    finally:
        sys.setprofile(None)
    for (caller, callee), calls in sorted(pairs.items()):
        print(f"{caller} -> {callee}  ({calls} calls)")
    print(f"module_boundaries={len(pairs)}")


if __name__ == "__main__":
    main()
