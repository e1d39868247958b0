"""Every setting of the project, declared once, and what is derived from the declarations.

The floor below ``sim``, ``contention`` and ``runs`` (docs/architecture.md). For now: ``parse``,
text to value for the command line (standard library only).
"""
