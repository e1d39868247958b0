"""How the paper's world is built: the one recipe from a run's configuration to its pre-drawn worlds.

It serves the single-user world (``edge``) that the YAFS core (``sim``), the runs, the API and
the Gymnasium environments replay, and lends its input and mobility rules to the contention world.
The floor above ``settings``, ``edge`` and ``methods`` and below ``sim``, ``contention`` and
``runs`` (docs/architecture.md, "Layers"); nothing is imported here: ``recipe`` reads traces with NumPy.
"""
