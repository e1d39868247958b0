"""Fixtures shared across the suite: the generated traces, use case 1's trace inputs with a
cheap compute model, and the paper's five-server scenario (each built once per session)."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from yafs_safetail.edge.inputs import TraceInputs, trace_inputs
from yafs_safetail.edge.scenario import (
    DEFAULT_PLACEMENT,
    DEFAULT_TOPOLOGY,
    REPOSITORY,
    EdgeScenario,
    load_scenario,
)
from yafs_safetail.edge.traces import TraceSet, load_traces
from yafs_safetail.edge.usecases import UseCase, get_use_case
from yafs_safetail.edge.world import load_inputs
from yafs_safetail.logs import PACKAGE_LOGGER, STDERR_HANDLER


@pytest.fixture(autouse=True)
def _no_logging_left_by_entry_points():
    """Entry points called in-process (``main(argv)``) set up logging for the process; each
    test starts from, and leaves, the state of a process that did not."""
    yield
    root = logging.getLogger()
    for handler in [h for h in root.handlers if h.name == STDERR_HANDLER]:
        root.removeHandler(handler)
    logging.getLogger(PACKAGE_LOGGER).setLevel(logging.NOTSET)


@pytest.fixture(scope="session")
def traces() -> TraceSet:
    return load_traces(REPOSITORY / "traces")


@pytest.fixture(scope="session")
def uc1_median_inputs(traces: TraceSet) -> TraceInputs:
    """Use case 1's inputs with the trace's median compute time at k as the compute 'model':
    deterministic and free of TensorFlow, so edge tests stay fast."""
    use_case = get_use_case(1)
    rough = trace_inputs(traces, use_case, lambda gamma, k: np.zeros(len(k)))
    median = rough.median_compute_by_k_s
    return trace_inputs(traces, use_case, lambda gamma, k: median[np.asarray(k) - 1])


@pytest.fixture(scope="session")
def paper_scenario() -> EdgeScenario:
    return load_scenario(DEFAULT_TOPOLOGY, DEFAULT_PLACEMENT)


@pytest.fixture(scope="session")
def uc1(paper_scenario: EdgeScenario) -> tuple[UseCase, EdgeScenario, TraceInputs]:
    """Use case 1 in the paper's scenario with its trace inputs (the trained compute model)."""
    use_case = get_use_case(1)
    return use_case, paper_scenario, load_inputs(use_case)
