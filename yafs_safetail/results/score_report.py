"""The scoring suite's report: one policy beside SafeTail, Oracle, the best fixed method and the
strongest simple policy in every scenario, with intervals paired by request.

Every method of a scenario meets the same requests (common random numbers), so the report pairs
them: a ratio's 95% interval comes from a paired moving-block bootstrap (:func:`paired_ratio`).
Each resample draws blocks of consecutive requests, within each seed, and applies the same
draws to both methods; blocks, because a request's latency follows its neighbours' (the load
trace, the queues), which an interval that resamples requests one by one would ignore.

``score_table`` gives the rows (``score.csv``), ``report_markdown`` the page (``REPORT.md``);
the figure is ``results.figures.score``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from yafs_safetail.methods.registry import baselines_of
from yafs_safetail.results.files import REQUESTS_FILE, read_requests_csv
from yafs_safetail.results.markdown import markdown_table

#: Bootstrap resamples of every interval (a fixed generator: the same folders give the same page).
RESAMPLES = 1000
BOOTSTRAP_SEED = 20261128
#: Resamples drawn at once (bounds the memory a large scenario takes).
_CHUNK = 50
#: The figures whose ratios the report gives, with their intervals.
RATIO_FIGURES = ("p50_s", "p99_s")


def scenario_requests(folder: Path, paper_world: bool) -> pd.DataFrame:
    """One seed's test requests of a scenario's run folder, every method's, as ``method,
    request, latency_s, servers, energy_j`` (a run's ``requests.csv`` test phase, or a sweep
    point's kept requests)."""
    if paper_world:  # a run's requests.csv, read through its checked reader
        frame = read_requests_csv(folder)
        frame = frame[frame["phase"] == "test"]
        # "servers" there lists the servers chosen ("1;3"); here it counts them.
        frame = frame.drop(columns="servers").rename(columns={"request_id": "request", "n_selected": "servers"})
    else:
        frame = pd.read_csv(folder / REQUESTS_FILE).rename(columns={"n_copies": "servers"})
    return frame[["method", "request", "latency_s", "servers", "energy_j"]].reset_index(drop=True)


_PERCENTILES = {"p50_s": 50.0, "p99_s": 99.0}


def _figures(values: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Each figure over the last axis, stacked last: a percentile of latencies (every percentile
    asked in one call, one partition), or a mean."""
    asked = [name for name in names if name in _PERCENTILES]
    found = dict(zip(asked, np.percentile(values, [_PERCENTILES[name] for name in asked], axis=-1), strict=True)) \
        if asked else {}
    return np.stack([found[name] if name in found else np.mean(values, axis=-1) for name in names], axis=-1)


def block_length(n_requests: int) -> int:
    """Consecutive requests per bootstrap block: √n, long enough to keep a queue's or a load
    minute's run of neighbours together, short enough for many distinct resamples."""
    return max(1, round(math.sqrt(n_requests)))


def _resample_indices(lengths: Sequence[int], rng: np.random.Generator, n_resamples: int) -> np.ndarray:
    """``n_resamples`` rows of indices into the seeds' requests laid end to end: per seed, as
    many blocks of consecutive requests (:func:`block_length`, wrapping round) as fill it."""
    parts = []
    offset = 0
    for n in lengths:
        block = block_length(n)
        n_blocks = -(-n // block)
        starts = rng.integers(0, n, size=(n_resamples, n_blocks))
        rows = (starts[:, :, None] + np.arange(block)) % n
        parts.append(rows.reshape(n_resamples, -1)[:, :n] + offset)
        offset += n
    return np.concatenate(parts, axis=1)


def resampled_figures(values: Mapping[str, Sequence[np.ndarray]], names: Sequence[str], rng: np.random.Generator,
                      n_resamples: int = RESAMPLES) -> dict[str, np.ndarray]:
    """Per method, each figure over ``n_resamples`` moving-block resamples of the requests, the
    same resamples for every method (paired): ``(n_resamples, len(names))``. ``values[m][s]``
    is method m's values in seed s, request by request in the requests' order."""
    lengths = [len(part) for part in next(iter(values.values()))]
    if any([len(part) for part in parts] != lengths for parts in values.values()):
        raise ValueError("paired resamples: the methods met different numbers of requests")
    joined = {method: np.concatenate(parts) for method, parts in values.items()}
    chunks: dict[str, list[np.ndarray]] = {method: [] for method in values}
    for start in range(0, n_resamples, _CHUNK):
        index = _resample_indices(lengths, rng, min(_CHUNK, n_resamples - start))
        for method, all_values in joined.items():
            chunks[method].append(_figures(all_values[index], names))
    return {method: np.concatenate(parts) for method, parts in chunks.items()}


def _ratio(mine: np.ndarray, theirs: np.ndarray, resampled_mine: np.ndarray,
           resampled_theirs: np.ndarray) -> tuple[float, float, float]:
    low, high = np.percentile(resampled_mine / resampled_theirs, [2.5, 97.5])
    return float(mine / theirs), float(low), float(high)


def paired_ratio(mine: Sequence[np.ndarray], theirs: Sequence[np.ndarray], figure: str,
                 rng: np.random.Generator, n_resamples: int = RESAMPLES) -> tuple[float, float, float]:
    """figure(mine) / figure(theirs) over every seed's requests, and its paired 95% moving-block
    bootstrap interval. ``mine[s]`` and ``theirs[s]`` are seed s's values request by request, in
    the requests' order (the same requests)."""
    resampled = resampled_figures({"mine": mine, "theirs": theirs}, [figure], rng, n_resamples)
    point = {name: _figures(np.concatenate(parts), [figure])[0] for name, parts in (("mine", mine), ("theirs", theirs))}
    return _ratio(point["mine"], point["theirs"], resampled["mine"][:, 0], resampled["theirs"][:, 0])


def _best_fixed(figures: pd.DataFrame) -> str | None:
    fixed = baselines_of(figures.index)  # Rand-x, MinLoad-x, MinProp-x: the fixed methods
    return min(fixed, key=lambda method: (figures.loc[method, "p99_s"], method)) if fixed else None


def comparators(methods: Sequence[str], mine: str, least_loaded: str, figures: pd.DataFrame) -> dict[str, str]:
    """Who a scenario sets the policy beside: role -> method (each SafeTail, Oracle, the best
    fixed method by p99, the strongest simple policy), those the scenario ran."""
    roles = {method: method for method in methods if method == "SafeTail" or method.startswith("SafeTail-")}
    if "Oracle" in methods:
        roles["Oracle"] = "Oracle"
    best = _best_fixed(figures)
    if best is not None:
        roles["best fixed"] = best
    if least_loaded in methods and least_loaded != mine:
        roles["least-loaded"] = least_loaded
    return roles


def score_table(requests: Mapping[str, Sequence[pd.DataFrame]], mine: str, least_loaded: str,
                seed: int = BOOTSTRAP_SEED) -> pd.DataFrame:
    """One row per (scenario, method): the method's figures over every seed's requests (median
    and p99 latency, servers and energy per request) and, for each method set beside ``mine``,
    ``mine``'s p50 and p99 over its with paired 95% intervals.

    Args:
        requests: per scenario, each seed's :func:`scenario_requests`.
        mine: the scored policy's method name.
        least_loaded: the strongest simple policy's method name.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for scenario, seeds in requests.items():
        methods = list(dict.fromkeys(seeds[0]["method"]))
        by_method = {method: [frame[frame["method"] == method].sort_values("request") for frame in seeds]
                     for method in methods}
        for method, parts in by_method.items():
            if any(not np.array_equal(part["request"], own["request"]) for part, own in zip(parts, by_method[mine],
                                                                                         strict=True)):
                raise ValueError(f"scenario {scenario}: {method} and {mine} met different requests; "
                                 "their ratios cannot be paired")
        pooled = {method: pd.concat(parts) for method, parts in by_method.items()}
        figures = pd.DataFrame({method: {
            "p50_s": float(np.percentile(part["latency_s"], 50)), "p99_s": float(np.percentile(part["latency_s"], 99)),
            "servers": float(part["servers"].mean()), "energy_j": float(part["energy_j"].mean())}
            for method, part in pooled.items()}).T
        roles = {mine: "your policy", **{method: role for role, method in
                                         comparators(methods, mine, least_loaded, figures).items()}}
        # One set of resamples for the scenario: every method's figures on the same requests.
        resampled = resampled_figures({method: [part["latency_s"].to_numpy() for part in by_method[method]]
                                       for method in roles}, RATIO_FIGURES, rng)
        for method, role in roles.items():
            row: dict[str, object] = {"scenario": scenario, "role": role, "method": method,
                                      "seeds": len(seeds), "requests": len(pooled[method]),
                                      **figures.loc[method].to_dict()}
            for column, figure in enumerate(RATIO_FIGURES):
                ratio, low, high = (_ratio(figures.loc[mine, figure], figures.loc[method, figure],
                                           resampled[mine][:, column], resampled[method][:, column])
                                    if method != mine else (1.0, 1.0, 1.0))
                row |= {f"ratio_{figure}": ratio, f"ratio_{figure}_low": low, f"ratio_{figure}_high": high}
            rows.append(row)
    return pd.DataFrame(rows)


def _interval(row: pd.Series, figure: str) -> str:
    return (f"{row[f'ratio_{figure}']:.3f} [{row[f'ratio_{figure}_low']:.3f}, "
            f"{row[f'ratio_{figure}_high']:.3f}]")


def verdict(row: pd.Series) -> str:
    """Whether the policy's p99 is below the other's, above it, or neither, at 95%."""
    if row["ratio_p99_s_high"] < 1:
        return "faster"
    if row["ratio_p99_s_low"] > 1:
        return "slower"
    return "no clear difference"


def glance_markdown(table: pd.DataFrame, roles: Sequence[str]) -> list[str]:
    """Per scenario, the policy's p99 over each role's, with its interval (and who the best
    fixed method was)."""
    header = ["scenario", "your p99 (s)", "your servers", *(f"÷ {role}" for role in roles)]
    lines = []
    for scenario, part in table.groupby("scenario", sort=False):
        by_role = part.set_index("role")
        mine = by_role.loc["your policy"]
        cells = [str(scenario), f"{mine['p99_s']:.3f}", f"{mine['servers']:.2f}"]
        for role in roles:
            if role not in by_role.index:
                cells.append("—")
                continue
            row = by_role.loc[role]
            name = f" ({row['method']})" if role == "best fixed" else ""
            cells.append(_interval(row, "p99_s") + name)
        lines.append(cells)
    return markdown_table(header, lines)


def scenario_markdown(part: pd.DataFrame) -> list[str]:
    """One scenario's table: each method's figures and the policy's ratios over them."""
    header = ["method", "role", "p50 (s)", "p99 (s)", "servers per request", "energy (J per request)",
              "your p50 ÷ its [95%]", "your p99 ÷ its [95%]"]
    rows = []
    for _, row in part.iterrows():
        mine = row["role"] == "your policy"
        rows.append([str(row["method"]), str(row["role"]), f"{row['p50_s']:.3f}", f"{row['p99_s']:.3f}",
                     f"{row['servers']:.2f}", f"{row['energy_j']:.3g}",
                     "—" if mine else _interval(row, "p50_s"), "—" if mine else _interval(row, "p99_s")])
    return markdown_table(header, rows)


def report_markdown(table: pd.DataFrame, mine: str, titles: Mapping[str, str], settings: Mapping[str, object],
                    command: str, figure: str | None) -> str:
    """REPORT.md: the answer first (how often the policy's p99 is clearly below or above
    SafeTail's), the glance table and figure, each scenario's table, how the intervals are
    computed and the suite's settings."""
    roles = [role for role in ("SafeTail", "Oracle", "best fixed", "least-loaded") if role in set(table["role"])]
    against = table[table["role"] == "SafeTail"]
    counts = {word: sum(verdict(row) == word for _, row in against.iterrows())
              for word in ("faster", "slower", "no clear difference")}
    lines = [f"# {mine} scored in {table['scenario'].nunique()} scenarios (profile {settings['name']})", "",
             f"**Against SafeTail's p99, {mine} is faster in {counts['faster']}, slower in {counts['slower']} "
             f"and not clearly different in {counts['no clear difference']} of {len(against)} scenarios** "
             "(95% intervals paired by request).", "",
             "A ratio is your policy's figure over the other method's: below 1, yours is lower (faster). "
             "`best fixed` is the fixed baseline (Rand-x, MinLoad-x, MinProp-x) with the lowest p99 in "
             "that scenario; `least-loaded` sends each request to the two least-loaded servers of all.", "",
             "## At a glance: your p99 over theirs", "", *glance_markdown(table, roles), ""]
    if figure:
        lines += [f"![your p99 over each method's, per scenario]({figure})", ""]
    lines += ["## Per scenario", ""]
    for scenario, part in table.groupby("scenario", sort=False):
        first = part.iloc[0]
        lines += [f"### {scenario}: {titles.get(str(scenario), '')}", "",
                  f"{first['seeds']} seed(s), {first['requests']} test requests per method.", "",
                  *scenario_markdown(part), ""]
    lines += ["## How the intervals are computed", "",
              "Every method of a scenario meets the same requests, in the same order, with the same random "
              "draws (common random numbers). Each interval is a paired moving-block bootstrap "
              f"({RESAMPLES} resamples): within each seed, blocks of √n consecutive requests are drawn "
              "with replacement (n: that seed's test requests), the same blocks for every method of the scenario; the "
              "figure is computed over every seed's resampled requests together; the interval is the "
              "2.5th and 97.5th percentiles of the ratios (docs/results.md, \"Paired intervals by request\").", "",
              "## The suite's settings", "", f"`{command}`", "", "```", *(f"{key}: {value}" for key, value in
                                                                       settings.items()), "```", ""]
    return "\n".join(lines)
