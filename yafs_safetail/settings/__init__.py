"""Every setting of the project, declared once: the run's, the world's, the contention world's parts.

It serves every world and engine from the lowest floor (the standard library and ``defaults``
only; docs/architecture.md, "Layers"): ``edge``, ``methods``, ``worlds``, both engines and the runs
read their settings and checks from here.

- ``declare``: how a setting is declared (:func:`~yafs_safetail.settings.declare.setting`:
  name, type, default, help, check, whether it changes results) and what is derived from the
  declarations (command-line options, configurations from them, checks, titles);
- ``checks``: what values a setting accepts (``Check``, the common checks, ``Names``);
- ``parse``: text to value for the command line (standard library only);
- ``world``: every world's settings (``WorldSettings``) and the ones a run may override
  (``WorldOverrides``), declared once for the experiment, the contention world, the sweeps and
  both Gymnasium environments;
- ``experiment``: the single-user run's configuration (``ExperimentConfig``).

Nothing is imported here: the commands build their parsers from ``declare``, ``world`` and
``experiment`` before NumPy loads. From a configuration to the worlds it draws is ``worlds.recipe``'s
(``world_recipe``, here, is its deprecated alias).
"""
