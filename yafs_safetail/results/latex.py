"""The cross-seed report's tables as LaTeX files, beside ``REPORT.md``.

Each table is made from the same frame of display strings as its markdown twin
(:func:`seed_tables.aggregate_table`, :func:`seed_tables.comparison_table`,
:func:`fidelity.scorecard_tables`), so a ``.tex`` file shows exactly the numbers ``REPORT.md``
shows, formatted the same way. pandas' ``DataFrame.to_latex`` (which renders through its Styler
and so needs jinja2) writes a ``table`` float with a booktabs ``tabular``, a caption and a label.

Escaping is done here, once, for cells, headers and captions alike, and ``to_latex`` is told not
to escape again: pandas leaves captions unescaped and knows nothing of the few non-ASCII symbols
the reports use (—, ±, ≤, Greek letters), which plain pdflatex rejects. The files need only
``\\usepackage{booktabs}``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from yafs_safetail.results.fidelity import (
    SCORECARD_ACCESS_NOTE,
    SCORECARD_RATIO_NOTE,
    TOLERANCE,
    scorecard_tables,
)
from yafs_safetail.results.files import write_text_atomic
from yafs_safetail.results.seed_tables import (
    AGGREGATE_NOTE,
    COMPARISON_NOTE,
    aggregate_table,
    comparison_table,
)

#: The folder, beside REPORT.md, that holds the ``.tex`` files.
TABLES_DIR = "tables"
TABLE_SUFFIX = ".tex"

#: The first line of every file: what it needs, so nobody has to guess from a compile error.
TABLE_PREAMBLE = "% Written by yafs-safetail from the run folders; needs \\usepackage{booktabs}.\n"

#: One replacement per character, applied in a single pass so that a replacement is never
#: escaped again (a naive chain of str.replace would turn the "\\" of "\\%" into a backslash
#: escape). Characters not listed here are kept as they are.
_ESCAPES: dict[str, str] = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    # In LaTeX's default OT1 text encoding "<", ">" and "|" print as other glyphs (¡, ¿, —).
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    "—": "---",
    "–": "--",
    "−": "$-$",
    "±": r"$\pm$",
    "≤": r"$\leq$",
    "≥": r"$\geq$",
    "×": r"$\times$",
    "≈": r"$\approx$",
    "·": r"$\cdot$",
    "∞": r"$\infty$",
    "…": r"\ldots{}",
    "β": r"$\beta$",
    "ε": r"$\varepsilon$",
    "κ": r"$\kappa$",
    "ν": r"$\nu$",
    "σ": r"$\sigma$",
    "τ": r"$\tau$",
    "ω": r"$\omega$",
}
_ESCAPE_PATTERN = re.compile("|".join(re.escape(c) for c in _ESCAPES))
#: Labels go into \label{} unescaped, so they are restricted to characters LaTeX takes there.
_LABEL_PATTERN = re.compile(r"[A-Za-z0-9:._-]+")


def latex_escape(text: str) -> str:
    """``text`` as LaTeX text-mode source: special characters escaped, the reports' symbols
    (—, ±, ≤, Greek letters, ...) turned into LaTeX commands."""
    return _ESCAPE_PATTERN.sub(lambda match: _ESCAPES[match.group(0)], text)


def _cell(value: object) -> str:
    text = latex_escape(str(value))
    # A row that starts with "[" right after the previous row's "\\" would be read as that
    # command's optional argument (a vertical space); "{}" ends the look-ahead.
    return "{}" + text if text.startswith("[") else text


def table_latex(table: pd.DataFrame, *, caption: str, label: str,
                column_format: str | None = None) -> str:
    """A frame of display strings as a LaTeX ``table`` (booktabs) via ``DataFrame.to_latex``.

    Args:
        table: one row per table row; its column names are the header. Cells are shown as
            ``str(value)``.
        caption: plain text (escaped here).
        label: the ``\\label`` (letters, digits and ``:._-`` only).
        column_format: the ``tabular`` column specification; default: the first column left,
            the others right-aligned.

    Returns:
        LaTeX source, starting with a one-line comment naming the package it needs.

    Raises:
        ValueError: the label has other characters, or ``column_format`` has a letter count that
            plainly cannot match the columns.
    """
    if not _LABEL_PATTERN.fullmatch(label):
        raise ValueError(f"LaTeX label {label!r}: only letters, digits and ':._-' are allowed")
    n_columns = len(table.columns)
    if column_format is None:
        column_format = "l" + "r" * (n_columns - 1)
    elif len(re.sub(r"\{[^}]*\}", "", column_format)) != n_columns:
        raise ValueError(f"column_format {column_format!r} does not describe {n_columns} columns")
    escaped = pd.DataFrame(
        [[_cell(value) for value in row] for row in table.itertuples(index=False)],
        columns=[latex_escape(str(name)) for name in table.columns], dtype=object,
    )
    body = escaped.to_latex(index=False, escape=False, column_format=column_format,
                            caption=latex_escape(caption), label=label, position="htbp")
    return TABLE_PREAMBLE + body


def latency_latex(stats: pd.DataFrame, *, use_case: int, use_case_name: str, preset: str,
                  digits: int = 3) -> str:
    """The per-use-case latency table across seeds (REPORT.md "Latency (test phase)").

    Args:
        stats: from :func:`stats.aggregate_summaries`.
        use_case, use_case_name, preset: for the caption and the label.
        digits: decimals shown (as in REPORT.md).
    """
    caption = (f"Use case {use_case} ({use_case_name}), preset {preset}: latency in seconds and "
               f"access rate (share of the servers a request is sent to). {AGGREGATE_NOTE}")
    return table_latex(aggregate_table(stats, digits), caption=caption,
                       label=f"tab:latency-uc{use_case}-{preset}")


def comparison_latex(aggregated: pd.DataFrame, *, use_case: int, preset: str,
                     only_stated: bool = False) -> str:
    """Our ratios beside the paper's (REPORT.md "Our ratios beside the paper's").

    Args:
        aggregated: from :func:`paper.aggregate_speedups`.
        use_case, preset: for the caption and the label.
        only_stated: keep only the rows for which the paper states a number.
    """
    caption = f"Use case {use_case}, preset {preset}: our ratios beside the paper's. {COMPARISON_NOTE}"
    # The note column holds sentences: a paragraph column wraps them instead of widening the page.
    return table_latex(comparison_table(aggregated, only_stated), caption=caption,
                       label=f"tab:ratios-uc{use_case}-{preset}",
                       column_format="rllrrrp{0.3\\linewidth}")


def scorecard_latex(card: pd.DataFrame, *, preset: str) -> dict[str, str]:
    """The fidelity scorecard's three tables (ratios, claims, SafeTail's access rate).

    Args:
        card: from :func:`fidelity.scorecard`.
        preset: for the captions and the labels.

    Returns:
        ``{"ratios": tex, "claims": tex, "access_rate": tex}``.
    """
    tables = scorecard_tables(card)
    return {
        "ratios": table_latex(
            tables["ratios"], label=f"tab:fidelity-{preset}-ratios",
            caption=(f"Fidelity scorecard, preset {preset}: the paper's ratios against ours "
                     f"(within tolerance: ours within {TOLERANCE:.0%} of the paper's). "
                     f"{SCORECARD_RATIO_NOTE}"),
            column_format="rlrrrll"),
        "claims": table_latex(
            tables["claims"], label=f"tab:fidelity-{preset}-claims",
            caption=f"Fidelity scorecard, preset {preset}: the paper's qualitative claims. "
                    "Our reading is written into the statement; holds = in most seeds.",
            column_format="rp{0.55\\linewidth}rl"),
        "access_rate": table_latex(
            tables["access_rate"], label=f"tab:fidelity-{preset}-access-rate",
            caption=f"Fidelity scorecard, preset {preset}: {SCORECARD_ACCESS_NOTE.rstrip(':')}.",
            column_format="rrl"),
    }


def write_tables(directory: str | os.PathLike[str], tables: Mapping[str, str]) -> list[Path]:
    """Write each table to ``directory/tables/<name>.tex`` (atomically), in the given order.

    Args:
        directory: the report's folder (the one holding REPORT.md).
        tables: file name without suffix -> LaTeX source.

    Returns:
        The written paths.
    """
    folder = Path(directory) / TABLES_DIR
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in tables.items():
        if not _LABEL_PATTERN.fullmatch(name):
            raise ValueError(f"table name {name!r}: only letters, digits and ':._-' are allowed")
        written.append(write_text_atomic(folder / f"{name}{TABLE_SUFFIX}", text))
    return written


def tables_markdown(paths: Sequence[Path], report_dir: Path) -> list[str]:
    """REPORT.md's list of the LaTeX tables, as markdown lines (paths relative to the report)."""
    lines = ["## LaTeX tables", "",
             "Every table above, as LaTeX (pandas `DataFrame.to_latex`; needs "
             "`\\usepackage{booktabs}`), the same numbers as here:", ""]
    lines += [f"- [`{os.path.relpath(p, report_dir)}`]({os.path.relpath(p, report_dir)})"
              for p in paths]
    return lines
