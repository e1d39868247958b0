"""A contention sweep's points as campaign runs: each point's run id, its ``RunSpec`` and the
run that writes its folder.

The sweep itself (every method at a point, one loop) is ``runs.sweep``'s; a campaign
(``runs.campaign``) executes each point on any engine (``runs.engines``'s ``RUN_KINDS``), so a
sweep is resumable and spread over workers as every campaign is.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from yafs_safetail.contention.world import ContentionError
from yafs_safetail.logs import RUN_LOG_FILE, Phase, run_log
from yafs_safetail.results.files import REQUESTS_FILE, write_text_atomic
from yafs_safetail.runs.grid import ID_LENGTH, RunSpec, code_version, file_identity
from yafs_safetail.runs.output import StagedOutput
from yafs_safetail.runs.sweep import run_sweep
from yafs_safetail.runs.sweep_config import LOAD_POINT, POINT_KINDS, ContentionSweep

log = logging.getLogger(__name__)

#: A point setting (absent unless true, so other points keep their ids): keep the test requests
#: one by one in the point's requests.csv (method, request, latency_s, n_copies, energy_j), for
#: intervals paired by request (``yafs-safetail score``).
PER_REQUEST = "per_request"


def method_identity(spec: str) -> dict[str, str]:
    """A user's policy in a point's identity: its name, class and file (place and contents, as
    every input file's), or its module."""
    name, sep, target = spec.partition("=")
    if not sep or ":" in name or "/" in name:  # no NAME= prefix (as methods.registry reads it)
        name, target = "", spec
    source, _, class_name = target.rpartition(":")
    if source.endswith(".py") or "/" in source or "\\" in source:
        return {"name": name, "class": class_name, **file_identity(Path(source))}
    return {"name": name, "class": class_name, "module": source}


def point_run_id(settings: Mapping[str, Any], kind: str = LOAD_POINT) -> str:
    """The short hash of everything a sweep point's rows depend on (its kind and settings, the
    input files' contents, the code version)."""
    identity = dict(settings, kind=kind, code_version=code_version())
    for key in ("topology", "placement"):
        identity[key] = file_identity(Path(settings[key]))
    if settings["user_conditions"] not in ("topology", "generated"):
        identity["user_conditions"] = file_identity(Path(settings["user_conditions"]))
    if settings.get("route") is not None:  # the route's contents, not only its name
        identity["route"] = file_identity(Path(settings["route"]))
    if settings.get("user_methods"):  # each user's policy file's contents too
        identity["user_methods"] = [method_identity(spec) for spec in settings["user_methods"]]
    if settings.get("traces_dir"):  # one's own traces: every file a run reads, by content
        from yafs_safetail.edge.traces import READ_FILES

        folder = Path(settings["traces_dir"])
        identity["traces_dir"] = [file_identity(folder / name) for name in READ_FILES
                                  if (folder / name).is_file()]
    canonical = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:ID_LENGTH]


def point_specs(config: ContentionSweep) -> list[RunSpec]:
    """One campaign run per point, points ascending (folder ``<axis folder>-<value>``)."""
    specs = []
    axis = config.axis
    for value in config.points:
        settings = config.point_settings(value)
        specs.append(RunSpec(name=f"{axis.folder}-{value:g}", run_id=point_run_id(settings, axis.kind),
                             settings=settings, kind=axis.kind))
    return specs


def run_sweep_point(spec: RunSpec, out_dir: Path, command: str = "", overwrite: bool = False) -> Path:
    """Run one point of a sweep (a campaign run of kind ``load_point`` or ``failure_point``)
    into ``out_dir``: its ``sweep.csv`` rows (and with :data:`PER_REQUEST` its test requests in
    ``requests.csv``), a ``run.json`` recording the run id and a ``run.log`` (staged; nothing is
    lost if it stops half way)."""
    import pandas as pd

    from yafs_safetail import __version__
    from yafs_safetail.contention.run import request_rows
    from yafs_safetail.versions import run_json_fields

    if spec.kind not in POINT_KINDS:
        raise ContentionError(f"run {spec.name}: kind {spec.kind!r} is not a sweep point; "
                              f"expected one of {', '.join(POINT_KINDS)}")
    config = POINT_KINDS[spec.kind].from_point_settings(spec.settings)
    output = StagedOutput(out_dir, overwrite)
    with output as staging:
        with run_log(staging / RUN_LOG_FILE):
            log.info("yafs-safetail %s: %s", __version__, command or "(run from Python)")
            log.info("%s point %s (run id %s): %s", config.axis.label, spec.name, spec.run_id,
                     ", ".join(f"{key}={value}" for key, value in spec.settings.items()))
            kept: list[pd.DataFrame] = []
            on_test_run = (lambda value, run: kept.append(request_rows(run))) if spec.settings.get(PER_REQUEST) else None
            with Phase(f"{spec.name} sweep", logger=log):
                frame = run_sweep(config, log=log.info, on_test_run=on_test_run)
            frame.to_csv(staging / "sweep.csv", index=False, float_format="%.6g")
            if kept:
                pd.concat(kept, ignore_index=True).to_csv(staging / REQUESTS_FILE, index=False, float_format="%.9g")
            write_text_atomic(staging / "run.json", json.dumps({
                "package_version": __version__, "campaign_run_id": spec.run_id, "kind": spec.kind,
                "command": command, "settings": dict(spec.settings), **run_json_fields()}, indent=1, sort_keys=True) + "\n")
        output.publish()
    return out_dir
