"""A new learning objective is one class: added here (in a fresh interpreter, to
``methods.objectives``) it is accepted by ``--objective`` and ``--objectives``, gives a sweep's
SafeTail its rows' name, preset and dispatch, follows the networks rule, and trains.
"""

from __future__ import annotations

from pathlib import Path

from source_addition import appended, run_probe

REPOSITORY = Path(__file__).resolve().parents[1]
#: The class, added to the module's source as it is imported: nothing on disk changes.
HOOK = appended("yafs_safetail.methods.objectives", """

class MixedTarget(Objective):
    \"\"\"Test only: §III's target vector mixed with the uniform one.\"\"\"

    name = "mixed-target"
    method_name = "SafeTail-M"

    def write_target(self, row, action, reward, n_servers):
        row[...] = 0.9 * target_vector(action, reward, n_servers) + 0.1 / len(row)
""")
PROBE = '''
import dataclasses, json
import numpy as np
from yafs_safetail.commands import load_sweep, run_usecase
from yafs_safetail.contention.config import ContentionError

def refused(call):
    try:
        call()
    except (ValueError, SystemExit) as error:
        return str(error)
    return None

report = {"run_refused": refused(lambda: run_usecase.parse_args(["--uc", "1", "--objective", "mixed-target",
                                                                 "--out", "unused"]))}
if ADD:
    from yafs_safetail.methods.safetail.learner import SafeTailLearner
    from yafs_safetail.methods.safetail.presets import get_preset
    run = run_usecase.parse_args(["--uc", "1", "--objective", "mixed-target", "--out", "unused"])
    args = load_sweep._parser().parse_args(["--objectives", "target-vector,mixed-target", "--out", "unused",
                                            "--loads", "0.3"])
    variants = load_sweep.sweep_configs(args)[0].safetails
    networks = load_sweep._parser().parse_args(["--objectives", "mixed-target", "--value-networks", "2",
                                                "--out", "unused", "--loads", "0.3"])
    from yafs_safetail.commands.sweeps import check_value_networks
    config = dataclasses.replace(get_preset("paper", 1, train_steps=64), objective="mixed-target", kappa=8,
                                 batch_size=4, replay_capacity=16)
    learner = SafeTailLearner(2, 6, config, seed=0)
    rng = np.random.default_rng(0)
    trained = [learner.observe(rng.random(6, dtype=np.float32), int(rng.integers(3)), -0.01) for _ in range(8)]
    report.update(
        run=run.objective,
        variants=[[v.name, v.learner, v.preset, v.dispatch, v.reward, v.n_networks] for v in variants],
        networks_refused=refused(lambda: check_value_networks(networks)),
        many_networks_refused=refused(lambda: dataclasses.replace(config, n_networks=2)),
        trained=trained[-1], targets_sum=float(learner._targets[0].sum()))
print(json.dumps(report))
'''


def _probe(add: bool) -> dict[str, object]:
    result: dict[str, object] = run_probe(HOOK, PROBE, add)
    return result


def test_a_new_objective_is_one_class() -> None:
    added, plain = _probe(True), _probe(False)
    assert "mixed-target" in str(plain["run_refused"])
    assert added["run_refused"] is None and added["run"] == "mixed-target"
    assert added["variants"] == [["SafeTail", "target-vector", "paper", "all", "paper", 1],
                                 ["SafeTail-M", "mixed-target", "paper", "all", "paper", 1]]
    assert "only with the value learner" in str(added["networks_refused"])
    assert "must be 1 with the 'mixed-target' objective" in str(added["many_networks_refused"])
    assert added["trained"] is True and abs(float(added["targets_sum"]) - 1.0) < 1e-5  # type: ignore[arg-type]
