"""A module's source with a few lines added as it is imported, in a fresh interpreter: how the
"a new X is one class or function" tests add one without touching a file on disk."""

from __future__ import annotations

#: Python run before a probe: with ``ADD`` true, MODULE's source gets ADDITION appended when it
#: is imported (never from cached bytecode); with ``ADD`` false, nothing changes.
_HOOK = """
import importlib.machinery, sys
MODULE = {module!r}
ADDITION = {addition!r}

class Loader(importlib.machinery.SourceFileLoader):
    def get_data(self, path):
        data = super().get_data(path)
        if path.endswith(".py"):
            data += ADDITION.encode()
        return data

    def path_stats(self, path):  # never a cached bytecode of the unchanged source
        raise OSError

class Finder(importlib.machinery.PathFinder):
    @classmethod
    def find_spec(cls, name, path=None, target=None):
        spec = super().find_spec(name, path, target)
        if spec is not None and name == MODULE:
            spec.loader = Loader(name, spec.origin)
        return spec

if ADD:
    sys.meta_path.insert(0, Finder)
"""


def source_hook(module: str, addition: str) -> str:
    """The code that adds ``addition`` to ``module``'s source when ``ADD`` is true."""
    return _HOOK.format(module=module, addition=addition)
