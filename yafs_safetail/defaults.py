"""What a command line shows before anything runs: the default input files and the names of the
choices, in a module that imports only the standard library.

``--help`` and a bad argument must answer at once (nothing heavy imported before the arguments
are checked), so the options' defaults and choices live here and the modules that use them
(``edge.scenario``, ``edge.traces``, ``edge.calibration``, ``sim.population``,
``methods.safetail.presets``) import them from here.

The default files (topologies/, placements/, traces/) sit in :data:`DATA_ROOT`:

- run from the project checkout (``PYTHONPATH=.`` or ``pip install -e .``): the checkout's root,
  where users edit them;
- installed from a wheel: the copy ``setup.py`` puts into the package as ``yafs_safetail/_data/``,
  so a run does not depend on the checkout.
"""

from __future__ import annotations

import argparse
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent
#: Where a built wheel carries the default files (setup.py's build step copies them there).
PACKAGED_DATA = _PACKAGE / "_data"
#: The folder holding topologies/, placements/ and traces/: the installed copy if there is one,
#: otherwise the source checkout the package is imported from.
DATA_ROOT = PACKAGED_DATA if PACKAGED_DATA.is_dir() else _PACKAGE.parent
#: The paper's five servers placed on a campus, the user with them: where a user moves
#: (docs/mobility.md; the mobility sweep's and the scoring suite's walking user).
CAMPUS_TOPOLOGY = DATA_ROOT / "topologies" / "campus_5servers.json"
#: The default files' folders, relative to :data:`DATA_ROOT`, and which of their files a wheel
#: must carry (setup.py copies exactly these; a test checks every default file is covered).
DATA_FILES: dict[str, tuple[str, ...]] = {
    "topologies": ("*.json",),
    "placements": ("*.json",),
    "routes": ("*.csv", "*.gpx"),
    "traces": ("*.csv", "README.md", "models/*.npz", "models/*.json", "models/*.keras"),
}
#: The lock: the exact library versions the published numbers and the golden files need
#: (docs/results.md, "Versions"). At the checkout's root, where ``pip install -c`` takes it; a
#: wheel carries a copy (setup.py), so an installed run can say when its versions differ.
LOCK_FILE_NAME = "constraints.txt"
LOCK_FILE = DATA_ROOT / LOCK_FILE_NAME

#: The paper's setting: five edge servers (§V-A).
DEFAULT_TOPOLOGY = DATA_ROOT / "topologies" / "paper_5servers.json"
DEFAULT_PLACEMENT = DATA_ROOT / "placements" / "paper_5servers.json"
#: The trace CSVs and, under models/, the compute models (traces/README.md).
DEFAULT_TRACE_DIR = DATA_ROOT / "traces"


def default_placement(topology: Path) -> Path:
    """The placement that goes with a topology file: ``placements/<its file name>``."""
    return DEFAULT_PLACEMENT if topology == DEFAULT_TOPOLOGY else DEFAULT_PLACEMENT.parent / topology.name


#: The learner presets (methods.safetail.presets defines each).
PRESET_NAMES = ("paper", "paper-literal", "tuned")
#: The paper's use cases (§V-A; edge.published re-exports them): 1 = YOLOv5 object detection,
#: 2 = instance segmentation, 3 = audio noise removal.
USE_CASES: tuple[int, ...] = (1, 2, 3)
#: The paper learner's method name (its rows' ``method``).
SAFETAIL = "SafeTail"
#: What SafeTail's network is trained to output (``LearnerConfig.objective``): §III's target
#: vector, the original code's Q-style targets (D18), or each action's value (D13). The names the
#: project ships; each is a class of ``methods.objectives``, whose registry the options accept.
OBJECTIVES = ("target-vector", "q-target", "value")
#: How SafeTail sends its subset (``SafeTailPolicy``'s ``dispatch``): every copy at once (the
#: paper), or tied copies cancelled once one starts running.
SAFETAIL_DISPATCH = ("all", "tied")
# The sweep commands' options name these three; methods.registry, methods.safetail.presets and
# methods.safetail.policy import them from here (those modules load NumPy).
#: What C(s_j) of Eq. 4 is: the compute trace's median at ν processes for every request, or that
#: median scaled to the request's own input (docs/deviations.md D11).
TARGET_COMPUTES = ("trace_median", "request")
#: How MinLoad-x and MinProp-x choose (docs/calibration.md rule 5): ``paper-text``, §V-B as
#: written (the x best of all n servers); ``original-code``, as the code that produced the
#: paper's numbers chose (three servers drawn at random per request, sorted stably, the first x).
BASELINE_READINGS = ("paper-text", "original-code")
#: How the user moves (edge.routes; docs/mobility.md): not at all, random waypoint, a route file.
MOBILITY_MODELS = ("off", "random-waypoint", "route")
#: Random waypoint's default speed range, m/s: walking.
WALKING_SPEED_MPS = (1.0, 1.5)
#: The mobility sweep's named speed ranges, m/s, slowest first: a user at rest; walking; urban
#: driving at 30 to 50 km/h.
MOBILITY_SPEEDS_MPS: dict[str, tuple[float, float]] = {
    "rest": (0.0, 0.0), "walking": WALKING_SPEED_MPS, "driving": (8.0, 14.0)}
#: How many servers the original code's MinLoad-x and MinProp-x drew before sorting.
ORIGINAL_CODE_CANDIDATES = 3
#: Simulated time between two requests: one load-trace row (one minute) per step.
DEFAULT_STEP_INTERVAL_S = 60.0

#: Every format a figure can be saved in, in the order they are written.
FIGURE_FORMATS: tuple[str, ...] = ("png", "pdf")
#: What a run draws unless asked (--figure-format): PDF copies take as long again as the PNGs.
DEFAULT_FIGURE_FORMATS: tuple[str, ...] = ("png",)


def figure_formats(text: str) -> tuple[str, ...]:
    """``"png"``, ``"pdf"`` or ``"png,pdf"`` -> the formats in FIGURE_FORMATS order.

    Raises:
        argparse.ArgumentTypeError: an unknown or empty format list (a command line reports it
            as a usage error naming the option).
    """
    asked = {part.strip().lower() for part in text.split(",") if part.strip()}
    if not asked or asked - set(FIGURE_FORMATS):
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected a comma-separated list of {', '.join(FIGURE_FORMATS)}")
    return tuple(fmt for fmt in FIGURE_FORMATS if fmt in asked)

#: The learning-rate rule's grid (docs/calibration.md rule 3; experiments/choose_learning_rate.py),
#: here so the command shows it without importing the runner.
LEARNING_RATE_GRID = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
