"""The one writer of Markdown tables: every report of the package (a run's ``summary.md``, the
tables across seeds, a sweep's SWEEP.md and FAILURE_SWEEP.md) writes its tables through it."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd


def format_number(value: float, digits: int = 3) -> str:
    """``value`` to ``digits`` decimals, or "—" when it is missing (None or NaN)."""
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else (
        f"{value:.{digits}f}"
    )


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A Markdown table's lines: the header, its rule, then one line per row of cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(row) + " |" for row in rows)
    return lines


def frame_markdown(table: pd.DataFrame) -> list[str]:
    """A frame of display strings (``results.seed_tables.aggregate_table``) as a table's lines."""
    return markdown_table([str(c) for c in table.columns],
                          [[str(v) for v in row] for row in table.itertuples(index=False)])


def frame_markdown_table(frame: pd.DataFrame) -> str:
    """A frame as a Markdown table, floats to three decimals (no final newline)."""
    def cell(value: object) -> str:
        return f"{value:.3f}" if isinstance(value, float | np.floating) else str(value)

    return "\n".join(markdown_table([str(c) for c in frame.columns],
                                    ([cell(v) for v in row] for row in frame.itertuples(index=False))))
