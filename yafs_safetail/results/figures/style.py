"""What every figure of the package shares: matplotlib's style, each method's colour, and the
writing of a figure's files.

One run's figures (:mod:`.run_figures`) and the figures across seeds (:mod:`.multiseed`) draw
with these, so that a method has the same colour in both and every file is written the same way.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from yafs_safetail import results
from yafs_safetail.defaults import DEFAULT_FIGURE_FORMATS

#: matplotlib's settings for every figure (``matplotlib.rc_context(STYLE)`` while drawing and
#: saving).
STYLE: dict[Any, Any] = {  # matplotlib types its keys as literals
    "font.size": 8.5,
    "axes.titlesize": 9,
    "axes.grid": True,
    "axes.axisbelow": True,
    "grid.alpha": 0.3,
    "legend.fontsize": 7.5,
    "legend.frameon": False,
    "axes.spines.top": False,
    "axes.spines.right": False,
}
PNG_DPI = 150
#: The training and the test phase's line colours.
PHASE_COLOURS = {"train": "#1f5fa8", "test": "#d64545"}

_FAMILY_COLOURS = {
    results.SAFETAIL: ("#1f5fa8",),
    results.ORACLE: ("#333333",),
    "Rand": ("#f2a65a", "#e07b24", "#a8520f"),
    "MinLoad": ("#8fd18a", "#4ca64a", "#23722a"),
    "MinProp": ("#f08a8a", "#d64545", "#962020"),
}
#: Users' own methods (``--method``), in report order.
_OWN_COLOURS = ("#7b4fa0", "#17a2a2", "#8c6d31", "#c44e97", "#7f7f7f")


def own_methods(present: Sequence[str]) -> list[str]:
    """The methods that are neither SafeTail, Oracle nor a baseline (users' policies)."""
    built_in = {results.SAFETAIL, results.ORACLE, *results.baselines_of(present)}
    return [m for m in results.sort_methods(present) if m not in built_in]


def colour(method: str, own: Sequence[str] = ()) -> str:
    """A method's colour: its family's, a shade per baseline level; ``own`` (from
    :func:`own_methods`) take theirs in order."""
    if method in own:
        return _OWN_COLOURS[min(list(own).index(method), len(_OWN_COLOURS) - 1)]
    family, level = results.parse_method(method)
    shades = _FAMILY_COLOURS.get(family, ("#7f7f7f",))
    index = 0 if level is None else min(level - 1, len(shades) - 1)
    return shades[index]


def save_figure(figure: Figure, folder: Path, stem: str,
                formats: Sequence[str] = DEFAULT_FIGURE_FORMATS) -> list[Path]:
    """Write ``folder/stem.<format>`` for each of ``formats``, each under a temporary name then
    renamed, so a crash never leaves a half-written figure behind; returns the files."""
    written = []
    for fmt in formats:
        dest = folder / f"{stem}.{fmt}"
        handle, tmp_name = tempfile.mkstemp(prefix=f".{stem}.", suffix=f".tmp.{fmt}", dir=folder)
        os.close(handle)
        try:
            # No creation date in the PDF: the same data gives the same bytes.
            metadata = {"CreationDate": None} if fmt == "pdf" else None
            figure.savefig(tmp_name, format=fmt, dpi=PNG_DPI, metadata=metadata)
            os.chmod(tmp_name, results.file_mode())
            os.replace(tmp_name, dest)
        except BaseException:
            if os.path.exists(tmp_name):
                os.unlink(tmp_name)
            raise
        written.append(dest)
    return written
