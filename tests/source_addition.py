"""A module's source changed as it is imported, in a fresh interpreter: how the "a new X is one
class, function or declaration" tests add one without touching a file on disk."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

REPOSITORY = Path(__file__).resolve().parents[1]

#: Python run before a probe: with ``ADD`` true, each module of CHANGES gets each text inserted
#: before its anchor (appended when the anchor is None) when it is imported, never from cached
#: bytecode; with ``ADD`` false, nothing changes.
_HOOK = """
import importlib.machinery, sys
CHANGES = {changes!r}

class Loader(importlib.machinery.SourceFileLoader):
    def get_data(self, path):
        data = super().get_data(path)
        if path.endswith(".py") and self.name in CHANGES:
            text = data.decode()
            for before, added in CHANGES[self.name]:
                if before is None:
                    text += added
                else:
                    assert before in text, (self.name, before)
                    text = text.replace(before, added + before, 1)
            data = text.encode()
        return data

    def path_stats(self, path):  # never a cached bytecode of the unchanged source
        raise OSError

class Finder(importlib.machinery.PathFinder):
    @classmethod
    def find_spec(cls, name, path=None, target=None):
        spec = super().find_spec(name, path, target)
        if spec is not None and name in CHANGES:
            spec.loader = Loader(name, spec.origin)
        return spec

if ADD:
    sys.meta_path.insert(0, Finder)
"""


def source_hook(changes: Mapping[str, Sequence[tuple[str | None, str]]]) -> str:
    """The code that, when ``ADD`` is true, changes each module named in ``changes`` as it is
    imported: each ``(before, text)`` inserts ``text`` before the first ``before`` in its source,
    or appends it when ``before`` is None."""
    return _HOOK.format(changes={module: list(edits) for module, edits in changes.items()})


def appended(module: str, text: str) -> str:
    """The code that appends ``text`` to ``module``'s source when ``ADD`` is true."""
    return source_hook({module: [(None, text)]})


def run_probe(hook: str, probe: str, add: bool, *args: str) -> Any:
    """Run ``probe`` (which prints one JSON value last) in a fresh interpreter after ``hook``,
    with the change made (``add``) or not; returns that value."""
    done = subprocess.run([sys.executable, "-c", f"ADD = {add}\n{hook}\n{probe}", *args], capture_output=True,
                          text=True, cwd=REPOSITORY, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])
