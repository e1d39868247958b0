"""What the sweep commands share (``load_sweep``, ``failure_sweep``; ``training_mechanism``
takes the world's options from here too): their options, derived from the declarations of
``contention.config.ContentionConfig`` and ``runs.sweep_config``, the world every point
shares, the checks that parsing alone cannot make, and the campaign every sweep is.

Not a command. Light at import, as every command's options must be (``tests/test_first_answer.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from yafs_safetail import __version__
from yafs_safetail.cli import add_plumbing, add_verbosity_options
from yafs_safetail.contention.config import ContentionConfig, ContentionError
from yafs_safetail.methods.objectives import averages_networks
from yafs_safetail.runs.engine_options import add_engine_options, engine_keywords
from yafs_safetail.runs.sweep_config import SWEEP_WORLD, ContentionSweep
from yafs_safetail.settings.options import add_options, config_from_args
from yafs_safetail.versions import run_json_fields

SweepT = TypeVar("SweepT", bound=ContentionSweep)

if TYPE_CHECKING:
    import pandas as pd

    from yafs_safetail.runs.grid import RunSpec

#: The sweep's settings given as options beside the axis's (each declared once in
#: runs.sweep_config), in the order --help lists them.
LEARNER_OPTIONS = ("steps_scale", "test_requests_per_load", "preset", "reward", "target", "objectives",
                   "n_networks", "dispatch")
#: The world's options every sweep opens with; the rest of the world's follow the learners'.
FIRST_WORLD_OPTIONS = ("use_case", "users")


def add_users_options(parser: argparse.ArgumentParser) -> None:
    """--uc and --users, every sweep's first options."""
    add_options(parser, ContentionConfig, only=FIRST_WORLD_OPTIONS, defaults=SWEEP_WORLD)


def add_world_options(parser: argparse.ArgumentParser) -> None:
    """Every other option of the contention world (servers, links, users' conditions, the input
    files, the world's overrides): each ContentionConfig field with an option, the seed aside
    (each command says how its seeds are given)."""
    add_options(parser, ContentionConfig, exclude=(*FIRST_WORLD_OPTIONS, "seed"), defaults=SWEEP_WORLD)


def add_output_options(parser: argparse.ArgumentParser, config_class: type[ContentionSweep]) -> None:
    """The methods, where the sweep goes and how it runs (every sweep's last options)."""
    add_options(parser, config_class, only=("methods", "user_methods", "safetail"))
    add_plumbing(parser, "--out", type=Path, required=True, help="new output folder")
    add_plumbing(parser, "--overwrite", action="store_true",
                 help="replace point folders there that hold another configuration's results")
    add_engine_options(parser)
    add_verbosity_options(parser)


def contention_base(args: argparse.Namespace, seed: int) -> ContentionConfig:
    """The contention world every point of a sweep shares, from the options."""
    base: ContentionConfig = config_from_args(args, ContentionConfig, seed=seed)
    check_mobility(base)
    check_traces(base)
    return base


def check_traces(base: ContentionConfig) -> None:
    """``--traces``: the folder and every file a point reads, before any point runs (one line
    naming the file, the row and the column; a point would otherwise fail in the campaign)."""
    if base.traces_dir is None:
        return
    folder = Path(base.traces_dir).expanduser()
    if not folder.is_dir():
        raise ContentionError(f"--traces {base.traces_dir}: no such folder")
    from yafs_safetail.edge.inputs import load_inputs
    from yafs_safetail.edge.usecases import get_use_case

    load_inputs(get_use_case(base.use_case), folder)


def check_mobility(base: ContentionConfig) -> None:
    """How the users move, checked before any point runs (one line, named as the options): the
    options that go together and, on the move, a topology that places every server and a
    route file read whole (a point would otherwise fail only once the campaign runs it)."""
    from yafs_safetail.worlds.recipe import check_mobility_settings

    check_mobility_settings(base, "option", ContentionError)
    if base.mobility == "off":
        return
    from yafs_safetail.edge.scenario import load_scenario
    from yafs_safetail.worlds.recipe import mobility_plan

    mobility_plan(base, load_scenario(Path(base.topology), Path(base.placement)), "option", ContentionError)


def check_methods(config: SweepT) -> SweepT:
    """The methods' names, which parsing alone cannot check, and each user's policy (``--method``)
    on its first request, as a one-line error before any point runs.

    Returns:
        ``config`` with any ``FILE.py:CLASS`` (or ``module:CLASS``) named in ``--methods`` moved
        to its users' policies, as if given with ``--method`` (a built-in name has no colon).
    """
    import numpy as np

    from yafs_safetail.methods.registry import UserMethod, make_baseline

    specs = [name for name in config.methods if ":" in name]
    if specs:
        config = replace(config, methods=tuple(name for name in config.methods if ":" not in name),
                         user_methods=(*config.user_methods, *(UserMethod(spec) for spec in specs)))

    for name in config.methods:  # unknown names fail before anything runs
        make_baseline(name, 5, np.random.default_rng(0))
    rows = [variant.name for variant in config.safetails] + list(config.methods)
    for method in config.user_methods:
        if method.name in rows:
            raise ContentionError(f"--method {method.spec}: the name {method.name!r} is taken by another "
                                  "method of the sweep; name it with NAME=")
        rows.append(method.name)
    check_user_methods(config)
    return config


def check_user_methods(config: ContentionSweep) -> None:
    """Ask each ``--method`` policy, built afresh, for the servers of the first point's first
    request (every server idle), so that one that cannot choose fails now, in one line
    (PolicyError), before any point is computed or SafeTail trained; as a run checks its own.

    Nothing a point uses is touched: the instance is a throwaway one with its own twin of the
    method's generator, and the world is one drawn for the check alone.
    """
    if not config.user_methods:
        return
    import dataclasses

    import numpy as np

    from yafs_safetail.contention.run import DISPATCH
    from yafs_safetail.contention.world import ContentionWorld
    from yafs_safetail.methods.registry import method_rng

    world = ContentionWorld(config.point_world(config.points[0]))
    first = world.observation(0, [0] * world.n_servers)
    for method in config.user_methods:
        # Arrays of its own for each policy: one may write into what it is given.
        copies: dict[str, Any] = {item.name: np.array(value) for item in dataclasses.fields(first)
                                  if isinstance(value := getattr(first, item.name), np.ndarray)}
        observation = dataclasses.replace(first, **copies)
        method.check_first_choice(world.n_servers, method_rng(config.base.seed, method.name), observation,
                                  DISPATCH, first="the sweep's first request")


def check_value_networks(args: argparse.Namespace) -> None:
    """--value-networks only with the value learner (one line, before the sweep is built)."""
    if args.n_networks is not None and not any(averages_networks(name) for name in args.objectives):
        raise ContentionError(f"--value-networks {args.n_networks}: only with the value learner "
                              "(SafeTail-CA)")


def check_test_requests(args: argparse.Namespace, config: ContentionSweep) -> None:
    """Enough test requests per point for a p99 (a one-line ContentionError otherwise)."""
    if config.test_requests < 100:
        flag = "--test-requests" if args.test_requests_per_load is not None else f"--steps-scale {args.steps_scale}"
        raise ContentionError(f"{flag}: {config.test_requests} test requests per {config.axis.label}; "
                              "at least 100 are needed for a p99")


def is_sweep_folder(folder: Path, kind: str, runs: tuple[str, ...]) -> bool:
    """A folder a sweep command made for ``kind``: a campaign's state file, and a sweep's
    run.json of that kind or nothing but the campaign's files and its run folders (named with
    one of ``runs``), so another campaign's folder or a results folder is never written into."""
    from yafs_safetail.runs.campaign import STATE_FILE

    if not (folder / STATE_FILE).is_file():
        return False
    if not (folder / "run.json").exists():
        # Interrupted before the table was assembled: only the campaign's files and run folders.
        return all(item.name.startswith((*runs, "campaign.", ".campaign.")) for item in folder.iterdir())
    try:
        return json.loads((folder / "run.json").read_text()).get("kind") == kind
    except (OSError, ValueError, AttributeError):
        return False


def check_out(out: Path, kind: str, runs: tuple[str, ...], what: str) -> None:
    """``--out`` is new, empty, or this kind of sweep's folder (``what`` names it in the error)."""
    if out.exists() and any(out.iterdir()) and not is_sweep_folder(out, kind, runs):
        raise ContentionError(f"--out {out}: exists and is not {what}'s folder; give a new folder")


def run_points(out: Path, specs: Mapping[int, Sequence[RunSpec]], args: argparse.Namespace,
               command: str) -> dict[int, pd.DataFrame] | None:
    """Every point of every seed's sweep as one campaign into ``out`` (each point cached by its
    configuration's hash, resumable, on any engine); each seed's rows read back from its points'
    folders, in point order. None when a point failed (the campaign has said which and why: a
    user's policy that fails mid-point in one line naming it); then no table is written, and a
    campaign that finished no point in a folder it made leaves nothing behind."""
    import pandas as pd

    from yafs_safetail.runs.campaign import (
        DONE,
        EARLIER,
        LOCK_FILE,
        LOG_FILE,
        STATE_FILE,
        run_campaign,
    )
    from yafs_safetail.runs.output import SWEEP_FILE

    existed = out.exists()
    fresh = not existed or not any(out.iterdir())
    result = run_campaign([spec for seed_specs in specs.values() for spec in seed_specs], out, command=command,
                          **engine_keywords(args))
    if result.failed:
        kept = "finished points are kept"
        if fresh and not any(state.status in (DONE, EARLIER) for state in result.runs):
            # Nothing to resume: the campaign's own files go too (a point's folder is staged, and
            # a failed one leaves none).
            for name in (STATE_FILE, LOG_FILE, LOCK_FILE):
                (out / name).unlink(missing_ok=True)
            if not existed and not any(out.iterdir()):
                out.rmdir()
            kept = "nothing was kept"
        print(f"error: {result.failed} point(s) failed (see above); no tables written; rerun the same command "
              f"to retry them ({kept})", file=sys.stderr)
        return None
    return {seed: pd.concat([pd.read_csv(out / spec.name / SWEEP_FILE) for spec in seed_specs], ignore_index=True)
            for seed, seed_specs in specs.items()}


def servers_word(base: ContentionConfig) -> str:
    """What a full server does, as --servers says it (the reports' and run.json's word)."""
    return "queue" if base.queue else "refuse"


def sweep_run_json(config: ContentionSweep, command: str, kind: str, specs: Sequence[RunSpec],
                   **axis: Any) -> dict[str, Any]:
    """A sweep folder's run.json: the command, the axis's settings (``axis``, in order after the
    use case and users), the world's and the methods', and each point's run id."""
    base = config.base
    return {
        "package_version": __version__, **run_json_fields(), "command": command, "kind": kind,
        "use_case": base.use_case, "users": base.users, **axis, "seed": base.seed,
        "steps_scale": config.steps_scale, "target": config.target,
        "safetails": [asdict(variant) for variant in config.safetails],
        "servers": servers_word(base), "cancel": base.cancel, "background": base.background, "links": base.links,
        "methods": list(config.methods),
        # Only when given (the users' policies by their specs, as each point records them).
        **({"user_methods": [method.spec for method in config.user_methods]} if config.user_methods else {}),
        "test_requests": config.test_requests,
        "topology": str(base.topology),
        "placement": str(base.placement), "user_conditions": str(base.user_conditions),
        **base.mobility_settings(),  # nothing when the users stay put
        **({"traces": str(base.traces_dir)} if base.traces_dir is not None else {}),
        f"{config.axis.folder}_runs": {spec.name.rsplit("/", 1)[-1]: spec.run_id for spec in specs}}


def safetail_lines(config: ContentionSweep) -> str:
    """How each SafeTail of the sweep learns and sends, one line each (none: fixed methods only)."""
    lines = [f"{variant.name}: {variant.describe()}, target `{config.target}`." for variant in config.safetails]
    return "".join(f"{line}\n\n" for line in lines)
