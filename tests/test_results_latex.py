"""LaTeX tables beside REPORT.md (yafs_safetail/results/latex.py): structure, escaping, numbers."""

from __future__ import annotations

import configparser
import math
import re
from pathlib import Path

import pandas as pd
import pytest
from results_helpers import write_seed_folders

from yafs_safetail import results
from yafs_safetail.results import fidelity, latex

REPOSITORY = Path(__file__).resolve().parents[1]
N_SEEDS = 3


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Three synthetic run folders of use case 1 (seeds 0, 1, 2)."""
    return write_seed_folders(tmp_path_factory.mktemp("latex"), N_SEEDS, 100)


def parse_table(tex: str) -> tuple[list[str], list[list[str]]]:
    """The header cells and the body rows of the one tabular in ``tex``, checking its frame."""
    assert tex.count("\\begin{table}") == 1 and tex.count("\\end{table}") == 1
    assert tex.count("\\begin{tabular}") == 1 and tex.count("\\end{tabular}") == 1
    assert tex.index("\\begin{table}") < tex.index("\\begin{tabular}") \
        < tex.index("\\end{tabular}") < tex.index("\\end{table}")
    lines = tex.splitlines()
    top, mid, bottom = (lines.index(rule) for rule in ("\\toprule", "\\midrule", "\\bottomrule"))
    assert top + 2 == mid < bottom

    def cells(line: str) -> list[str]:
        assert line.endswith(" \\\\"), line
        # An escaped "\&" is text, not a column separator.
        return [c.strip() for c in re.split(r"(?<!\\)&", line[: -len(" \\\\")])]

    return cells(lines[top + 1]), [cells(line) for line in lines[mid + 1 : bottom]]


def caption_and_label(tex: str) -> tuple[str, str]:
    caption = re.search(r"\\caption\{(.*)\}\n", tex)
    label = re.search(r"\\label\{([^}]*)\}", tex)
    assert caption and label
    return caption.group(1), label.group(1)


def interval_cell(mean: float, low: float, high: float, digits: int) -> str:
    if math.isnan(low):
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


# ---------------------------------------------------------------------------- escaping


@pytest.mark.parametrize(("text", "expected"), [
    ("Rand-1", "Rand-1"),
    ("50%", "50\\%"),
    ("A_b & c", "A\\_b \\& c"),
    ("$#{}", "\\$\\#\\{\\}"),
    ("a\\b", "a\\textbackslash{}b"),
    ("~^", "\\textasciitilde{}\\textasciicircum{}"),
    ("x <= 2 | y > 1", "x \\textless{}= 2 \\textbar{} y \\textgreater{} 1"),
    ("within ±20%", "within $\\pm$20\\%"),
    ("—", "---"),
    ("goal ≤ 0.5", "goal $\\leq$ 0.5"),
    ("final ε, β = 20", "final $\\varepsilon$, $\\beta$ = 20"),
])
def test_latex_escape(text: str, expected: str) -> None:
    assert latex.latex_escape(text) == expected


def test_escaping_is_one_pass_and_leaves_ascii() -> None:
    # "\\%" must not become "\\textbackslash{}\\%" style double escapes of our own output.
    assert latex.latex_escape("%\\") == "\\%\\textbackslash{}"
    escaped = latex.latex_escape("—±≤≥×≈·∞…βεκνστω−–")
    assert escaped.isascii()


def test_special_characters_in_cells_headers_and_caption() -> None:
    table = pd.DataFrame([["A_b & 50%", "[0.1, 0.2]"], ["Rand-1", "—"]],
                         columns=["method #", "rate (%)"])
    tex = latex.table_latex(table, caption="Share in % & more", label="tab:x-1")
    header, rows = parse_table(tex)
    assert header == ["method \\#", "rate (\\%)"]
    # A cell that starts with "[" would be read as the optional argument of the row's "\\".
    assert rows == [["A\\_b \\& 50\\%", "{}[0.1, 0.2]"], ["Rand-1", "---"]]
    assert caption_and_label(tex) == ("Share in \\% \\& more", "tab:x-1")
    assert "\\begin{tabular}{lr}" in tex
    assert tex.startswith("% ") and "booktabs" in tex.splitlines()[0]


def test_bad_label_and_column_format_are_refused() -> None:
    table = pd.DataFrame([["a", "b"]], columns=["x", "y"])
    with pytest.raises(ValueError, match="label"):
        latex.table_latex(table, caption="c", label="tab:a b")
    with pytest.raises(ValueError, match="column_format"):
        latex.table_latex(table, caption="c", label="tab:a", column_format="lrr")
    # A paragraph column counts as one column.
    assert "{lp{0.3\\linewidth}}" in latex.table_latex(table, caption="c", label="tab:a",
                                                         column_format="lp{0.3\\linewidth}")


def test_jinja2_is_declared_because_to_latex_needs_it() -> None:
    config = configparser.ConfigParser()
    config.read(REPOSITORY / "setup.cfg")
    requirements = [line.split("#")[0].strip() for line in
                    config["options"]["install_requires"].splitlines()]
    assert any(re.match(r"jinja2\b", r, re.IGNORECASE) for r in requirements)


# ---------------------------------------------------------------------------- the tables


def test_latency_table_has_a_row_per_method_and_the_frames_numbers(folders: list[Path]) -> None:
    stats = results.aggregate_summaries(folders)
    tex = latex.latency_latex(stats, use_case=1, use_case_name="object detection (YOLOv5)",
                              preset="paper")
    header, rows = parse_table(tex)
    assert header == ["method", "seeds", "median (s)", "p90 (s)", "p95 (s)", "p99 (s)",
                      "mean access rate", "mean target (s)"]
    methods = results.sort_methods(stats["method"].unique())
    assert [row[0] for row in rows] == methods and len(rows) == 11
    metrics = ["p50_s", "p90_s", "p95_s", "p99_s", "mean_access_rate", "mean_target_s"]
    for row in rows:
        part = stats[stats["method"] == row[0]].set_index("metric")
        assert row[1] == str(N_SEEDS)
        for cell, metric in zip(row[2:], metrics, strict=True):
            entry = part.loc[metric]
            assert not math.isnan(entry["ci_low"])
            assert cell == interval_cell(entry["mean"], entry["ci_low"], entry["ci_high"], 3)
    caption, label = caption_and_label(tex)
    assert label == "tab:latency-uc1-paper"
    assert "Use case 1" in caption and "95\\% bootstrap interval" in caption


def test_latency_table_with_one_seed_has_no_intervals(folders: list[Path]) -> None:
    stats = results.aggregate_summaries(folders[:1])
    _, rows = parse_table(latex.latency_latex(stats, use_case=1, use_case_name="x",
                                              preset="paper"))
    safetail = stats[stats["method"] == "SafeTail"].set_index("metric")
    assert rows[0][0] == "SafeTail" and rows[0][2] == f"{safetail.loc['p50_s', 'mean']:.3f}"
    assert not any("[" in cell for row in rows for cell in row)


def test_latex_and_markdown_show_the_same_cells(folders: list[Path]) -> None:
    stats = results.aggregate_summaries(folders)
    markdown = results.frame_markdown(results.aggregate_table(stats))
    md_rows = [[c.strip() for c in line.strip("|").split("|")] for line in markdown[2:]]
    _, tex_rows = parse_table(latex.latency_latex(stats, use_case=1, use_case_name="x",
                                                  preset="paper"))
    assert md_rows == tex_rows


def test_ratio_table(folders: list[Path]) -> None:
    aggregated = results.aggregate_speedups(folders)
    tex = latex.comparison_latex(aggregated, use_case=1, preset="paper-literal")
    header, rows = parse_table(tex)
    assert header == ["use case", "comparison", "percentile", "ours", "seeds", "paper", "differs?"]
    assert len(rows) == len(aggregated)
    for row, entry in zip(rows, aggregated.itertuples(index=False), strict=True):
        assert row[1] == f"{entry.method} over {entry.reference}"
        assert row[3] == interval_cell(entry.mean, entry.ci_low, entry.ci_high, 2)
        assert row[5] == ("---" if math.isnan(entry.paper) else f"{entry.paper:.2f}")
        assert row[6] == latex.latex_escape(entry.note)
    # Notes with a percent sign ("inside our 95% interval") keep it escaped.
    assert not any(re.search(r"(?<!\\)%", row[6]) for row in rows)
    assert "p{0.3\\linewidth}" in tex
    assert caption_and_label(tex)[1] == "tab:ratios-uc1-paper-literal"
    only = parse_table(latex.comparison_latex(aggregated, use_case=1, preset="paper",
                                              only_stated=True))[1]
    assert len(only) == int(aggregated["paper"].notna().sum()) > 0


def test_scorecard_tables(folders: list[Path]) -> None:
    card = fidelity.scorecard({1: [results.read_summary_csv(f) for f in folders]})
    tables = latex.scorecard_latex(card, preset="paper")
    assert list(tables) == ["ratios", "claims", "access_rate"]
    header, rows = parse_table(tables["ratios"])
    assert header[5] == "within $\\pm$20\\%"
    ratios = card[card["kind"] == "ratio"]
    assert len(rows) == len(ratios) == 16
    for row, entry in zip(rows, ratios.itertuples(index=False), strict=True):
        assert row[1] == entry.key and row[2] == f"{entry.paper:.2f}"
        assert row[3] == interval_cell(entry.ours, entry.ci_low, entry.ci_high, 2)
        assert row[4] == f"{entry.relative_error:+.0%}".replace("%", "\\%")
        assert row[6] == entry.subset
    _, claim_rows = parse_table(tables["claims"])
    claims = card[card["kind"] == "claim"]
    assert [r[1] for r in claim_rows] == [latex.latex_escape(s) for s in claims["statement"]]
    assert all(r[2].endswith(f"\\% of {N_SEEDS}") for r in claim_rows)
    header, access_rows = parse_table(tables["access_rate"])
    access = card[card["kind"] == "access_rate"].iloc[0]
    assert access_rows == [["1", interval_cell(access["ours"], access["ci_low"],
                                               access["ci_high"], 3),
                            "yes" if access["within_tolerance"] else "no"]]
    assert "$\\leq$ 0.5" in caption_and_label(tables["access_rate"])[0]
    for tex in tables.values():
        assert tex.isascii()


def test_write_tables(tmp_path: Path) -> None:
    table = latex.table_latex(pd.DataFrame([["a"]], columns=["x"]), caption="c", label="tab:c")
    written = latex.write_tables(tmp_path, {"one": table, "two": table})
    assert written == [tmp_path / "tables" / "one.tex", tmp_path / "tables" / "two.tex"]
    assert written[0].read_text() == table
    assert sorted(p.name for p in (tmp_path / "tables").iterdir()) == ["one.tex", "two.tex"]
    with pytest.raises(ValueError, match="table name"):
        latex.write_tables(tmp_path, {"../escape": table})
    lines = latex.tables_markdown(written, tmp_path)
    assert "- [`tables/one.tex`](tables/one.tex)" in lines
