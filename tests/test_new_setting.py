"""A new world setting is one declaration: added here (in a fresh interpreter, to
``settings.world.WorldSettings``, with the ``same_as`` line that lets a run override it in
``WorldOverrides``) it becomes a checked field of every world, an option of the run and of the
load sweep, a field of both configurations, a keyword of both Gymnasium environments, and part
of the run id only when set.
"""

from __future__ import annotations

from pathlib import Path

from source_addition import run_probe, source_hook

REPOSITORY = Path(__file__).resolve().parents[1]
#: Adds the setting to the sources as they are imported: nothing on disk changes.
HOOK = source_hook({
    "yafs_safetail.settings.world": [
        ("    baseline_reading: str = setting(",
         "    link_jitter: float = setting(1.0, 'a test-only world setting', check=POSITIVE_NUMBER)\n"),
        ("    baseline_reading: str | None = same_as(",
         "    link_jitter: float | None = same_as(WorldSettings, 'link_jitter', None)\n"),
    ],
})
PROBE = '''
import json, dataclasses, inspect
from yafs_safetail.commands import load_sweep, run_usecase
from yafs_safetail.contention.config import ContentionConfig
from yafs_safetail.runs.grid import config_run_id
from yafs_safetail.settings.experiment import ExperimentConfig
report = {"default_run_id": config_run_id(ExperimentConfig())}
if ADD:
    from yafs_safetail.contention.env import ContentionEnv
    from yafs_safetail.sim.env import SafeTailEnv
    run = run_usecase.parse_args(["--uc", "1", "--link-jitter", "0.5", "--out", "unused"])
    sweep_args = load_sweep._parser().parse_args(["--link-jitter", "0.5", "--out", "unused", "--loads", "0.3"])
    sweep = load_sweep.sweep_configs(sweep_args)[0]
    env = SafeTailEnv(use_case=1, steps_scale=0.02, link_jitter=0.5)
    contention = ContentionEnv(use_case=1, n_requests=20, link_jitter=0.5)
    contention.reset(seed=1)
    contention_world = contention.world.settings.link_jitter
    contention.close()
    try:
        run_usecase.parse_args(["--uc", "1", "--link-jitter", "-1"])
        refused = None
    except ValueError as error:
        refused = str(error)
    from yafs_safetail.edge.calibration import LANDED, CalibrationError
    try:  # the world's own check is the declaration's too
        dataclasses.replace(LANDED, link_jitter=0.0)
        world_refused = None
    except CalibrationError as error:
        world_refused = str(error)
    report.update(
        run=run.link_jitter, run_help="--link-jitter" in run_usecase._parser().format_help(), refused=refused,
        world_default=LANDED.link_jitter, world_refused=world_refused,
        sweep=sweep.base.link_jitter, sweep_point=sweep.point_settings(0.3).get("link_jitter"),
        sweep_help="--link-jitter" in load_sweep._parser().format_help(),
        env=env._recipe.settings.link_jitter, env_overrides=env._recipe.overrides,
        env_keyword="link_jitter" in inspect.signature(SafeTailEnv).parameters,
        contention=contention.config.link_jitter, contention_world=contention_world,
        contention_keyword="link_jitter" in inspect.signature(ContentionEnv).parameters,
        set_run_id_differs=config_run_id(ExperimentConfig(link_jitter=0.5)) != report["default_run_id"],
        contention_field="link_jitter" in {f.name for f in dataclasses.fields(ContentionConfig)})
print(json.dumps(report))
'''


def _probe(add: bool) -> dict[str, object]:
    result: dict[str, object] = run_probe(HOOK, PROBE, add)
    return result


def test_a_world_setting_declared_once_reaches_every_command_and_environment() -> None:
    added, plain = _probe(True), _probe(False)
    assert added["run"] == 0.5 and added["run_help"]
    assert "--link-jitter" in str(added["refused"])
    assert added["world_default"] == 1.0 and "link_jitter=0.0 is out of range" in str(added["world_refused"])
    assert added["sweep"] == 0.5 and added["sweep_point"] == 0.5 and added["sweep_help"]
    assert added["env"] == 0.5 and added["env_overrides"] == {"link_jitter": 0.5} and added["env_keyword"]
    assert added["contention"] == 0.5 and added["contention_world"] == 0.5
    assert added["contention_keyword"] and added["contention_field"]
    # Hashed only when set: every existing configuration keeps its run id.
    assert added["set_run_id_differs"] and added["default_run_id"] == plain["default_run_id"]
