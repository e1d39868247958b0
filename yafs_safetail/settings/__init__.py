"""Every setting of the project, declared once, and the world a configuration makes.

The floor below ``sim``, ``contention`` and ``runs`` (docs/architecture.md):

- ``declare``: how a setting is declared (:func:`~yafs_safetail.settings.declare.setting`:
  name, type, default, help, check, whether it changes results) and what is derived from the
  declarations (command-line options, configurations from them, checks, titles);
- ``parse``: text to value for the command line (standard library only);
- ``world``: the world's settings a run may override (``WorldOverrides``), declared once for
  the experiment, the contention world, the sweeps and both Gymnasium environments;
- ``experiment``: the single-user run's configuration (``ExperimentConfig``).

Nothing is imported here: the commands build their parsers from ``declare``, ``world`` and
``experiment`` before NumPy loads. From a configuration to the worlds it draws is ``worlds.recipe``'s
(``world_recipe``, here, is its deprecated alias).
"""
