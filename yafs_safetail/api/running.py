"""The API's running half: :func:`run`, a run from keywords (the command's checks and folder),
and ``ApiError``, the API's one error. Light to import (``yafs_safetail.api``)."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from yafs_safetail.defaults import default_placement
from yafs_safetail.settings.declare import check_config
from yafs_safetail.settings.experiment import ExperimentConfig

if TYPE_CHECKING:
    from yafs_safetail.methods.policy import Policy
    from yafs_safetail.methods.registry import UserMethod


class ApiError(ValueError):
    """A bad argument to a function of ``yafs_safetail.api`` (one line naming it and what is wrong)."""


#: Fields :func:`run` does not take as settings: its own arguments (``use_case``, ``out_dir``,
#: ``methods``), and what it sets itself (the call it records as the command; a campaign's id).
_SET_BY_RUN = ("command", "run_id", "methods", "out_dir", "use_case")
#: Every keyword :func:`run` takes besides ``use_case``, ``out_dir`` and ``methods``: the fields of
#: ``settings.experiment.ExperimentConfig`` (docs/usage.md lists them as options).
SETTINGS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(ExperimentConfig)
                                  if f.name not in _SET_BY_RUN)


def _user_method(method: str | type[Policy] | UserMethod) -> UserMethod:
    """A ``methods`` entry as the run takes it: a ``[NAME=]file.py:Class`` or ``module:Class``
    spec, an already parsed ``UserMethod``, or a ``Policy`` subclass defined at the top level of
    a module (a notebook's cells are the module ``__main__``)."""
    from yafs_safetail.methods.policy import Policy
    from yafs_safetail.methods.registry import UserMethod

    if isinstance(method, UserMethod):
        return method
    if isinstance(method, str):
        return UserMethod(method)
    if isinstance(method, type) and issubclass(method, Policy):
        module = sys.modules.get(method.__module__)
        # The run finds the class again by its module and name (forked workers build their own
        # instances, and run.json records the spec), so it must be reachable that way.
        if getattr(module, method.__name__, None) is not method:
            raise ApiError(f"run(): methods: {method.__qualname__} is not reachable as "
                           f"{method.__module__}.{method.__name__}; define it at the top level of a "
                           "module or notebook cell")
        return UserMethod(f"{method.__module__}:{method.__name__}")
    raise ApiError(f"run(): methods: {method!r} is neither 'file.py:Class', 'module:Class' nor a "
                   "Policy subclass")


def _default_out_dir(config: ExperimentConfig) -> Path:
    """The command's default folder (``results/uc<N>-<preset>-s<seed>...``), relative to the
    working folder, so a run from Python lands where the same command's would."""
    from yafs_safetail.commands.run_usecase import default_out_dir

    return default_out_dir(argparse.Namespace(
        use_case=config.use_case, preset=config.preset, seed=config.seed,
        steps_scale=config.steps_scale, learning_rate=config.learning_rate,
        objective=config.objective, baseline_reading=config.baseline_reading,
        topology=config.topology))


def _call_text(use_case: int, out_dir: Path, methods: Sequence[UserMethod],
               settings: dict[str, Any]) -> str:
    """The call as run.json records it, in place of a command line."""
    parts = [repr(use_case), f"out_dir={str(out_dir)!r}"]
    if methods:
        parts.append(f"methods={[m.spec for m in methods]!r}")
    parts += [f"{name}={value!r}" for name, value in settings.items()]
    return f"yafs_safetail.api.run({', '.join(parts)})"


def run(use_case: int = 1, *, out_dir: str | os.PathLike[str] | None = None,
        methods: Iterable[str | type[Policy] | UserMethod] = (), **settings: Any) -> Path:
    """Train SafeTail on one use case, test it and every other method, write the results folder.

    The same run as ``yafs-safetail run --uc USE_CASE ...`` (identical results files for the
    same settings, apart from the command ``run.json`` records). Progress bars are off unless
    ``progress=True``; the run logs its phases through :mod:`logging` (logger ``yafs_safetail``).

    Args:
        use_case: 1 object detection, 2 instance segmentation, 3 noise removal.
        out_dir: the results folder (default: the command's, ``results/uc<N>-<preset>-s<seed>``
            plus ``-x<scale>`` with ``steps_scale``, relative to the working folder). Written only
            when the run succeeds; an earlier results folder there is replaced only with
            ``overwrite=True``.
        methods: your own policies beside the built-in ones: ``Policy`` subclasses (defined at the
            top level of a module or notebook), ``"file.py:Class"`` or ``"module:Class"`` specs
            (``"NAME=file.py:Class"`` names it in the results).
        **settings: any of :data:`SETTINGS` (``settings.experiment.ExperimentConfig``'s fields:
            ``seed``, ``preset``, ``steps_scale``, ``redundancy_levels``, ``topology``,
            ``figures``, ``workers``, ``overwrite``, ``target_latency_s``...), checked as the
            command checks its options. ``placement`` defaults to the topology's.

    Returns:
        The results folder (see :func:`read_results`).

    Raises:
        ValueError: an unknown or bad setting, a bad input file or policy (one line naming it);
            nothing is written then.
        OSError: the folder cannot be written.
    """
    unknown = sorted(set(settings) - set(SETTINGS))
    if unknown:
        raise ApiError(f"run(): {unknown[0]!r} is not a setting; the settings are "
                       f"{', '.join(SETTINGS)}")
    values = dict(settings)
    for name in ("topology", "placement", "traces_dir", "policy", "down_intervals"):
        if values.get(name) is not None:
            values[name] = Path(values[name])
    if isinstance(values.get("redundancy_levels"), list | range):  # anything else: the check says
        values["redundancy_levels"] = tuple(values["redundancy_levels"])
    if "placement" not in values and "topology" in values:
        values["placement"] = default_placement(values["topology"])
        if not values["placement"].is_file() and values["topology"].is_file():
            # The loader would name a file the caller never gave: say where it came from.
            raise ApiError(f"run(): placement: {values['placement']} not found, the default for "
                           f"topology {values['topology']}; pass placement=")
    values.setdefault("progress", False)  # a notebook's stderr shows bars as a wall of lines
    user_methods = tuple(_user_method(m) for m in methods)
    config = ExperimentConfig(use_case=use_case, methods=user_methods, **values)
    check_config(config, style="field")  # errors name the keyword, not the command's option
    folder = Path(out_dir) if out_dir is not None else _default_out_dir(config)
    config = dataclasses.replace(config, out_dir=folder,
                                 command=_call_text(use_case, folder, user_methods, settings))
    # TensorFlow's C++ start-up notes say nothing about the run (as run_cli); an explicit
    # TF_CPP_MIN_LOG_LEVEL in the environment still wins.
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")
    from yafs_safetail.runs.experiment import run_experiment  # NumPy, simpy, maybe TensorFlow

    return run_experiment(config).out_dir
