"""Where a relative input path a user wrote points: next to where it was written, else the
packaged default file of that name.

A grid written in one folder and run from another must read the same files, and a new user who
names ``topologies/paper_5servers.json`` from an empty folder means the default that travels
with the package (:data:`~yafs_safetail.defaults.DATA_ROOT`), as a run without ``--topology``
reads it. The rule, for a relative path ``P`` written in folder ``F`` (a grid's folder):

1. ``F/P`` if it exists: the user's own file wins, also over a packaged default of the same
   name (what sits beside the grid is what its author sees and edits);
2. otherwise, when ``P`` starts with one of the default folders (``topologies/``,
   ``placements/``, ``traces/``: :data:`~yafs_safetail.defaults.DATA_FILES`), ``DATA_ROOT/P``
   if it exists;
3. otherwise ``F/P``, which does not exist: the caller reports it.

Only the default folders fall back, so a path resolves the same way from a checkout and from an
installed wheel (in a checkout ``DATA_ROOT`` is the checkout's root, which holds far more than
the default files). Standard library and ``defaults`` only: a command may resolve its options
before NumPy loads.
"""

from __future__ import annotations

from pathlib import Path

from yafs_safetail.defaults import DATA_FILES, DATA_ROOT


def packaged_default(path: str | Path) -> Path | None:
    """The packaged default file (or folder) a relative path names, or None.

    Args:
        path: a path as the user wrote it, e.g. ``topologies/3servers.json``.

    Returns:
        ``DATA_ROOT/path`` when ``path`` is relative, starts with a default folder and exists
        there; otherwise None.
    """
    given = Path(path)
    if given.is_absolute() or not given.parts or given.parts[0] not in DATA_FILES:
        return None
    candidate = DATA_ROOT / given
    return candidate.resolve() if candidate.exists() else None


def resolve_input(path: str | Path, folder: Path) -> Path:
    """An input path as the module's rule resolves it, absolute.

    Args:
        path: the path as written (``~`` is expanded).
        folder: where it was written: the grid file's folder (a command line's would be the
            working folder).

    Returns:
        The absolute path of the user's file, else of the packaged default, else the path
        next to ``folder`` (which does not exist: the caller names it in its error).
    """
    given = Path(path).expanduser()
    own = (folder / given).resolve()  # an absolute ``given`` replaces ``folder``
    if own.exists() or given.is_absolute():
        return own
    return packaged_default(given) or own
