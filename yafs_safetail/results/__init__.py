"""The results folder and everything computed from it (never from the simulator): tables, reports, figures.

It serves both worlds alike, the paper's single-user runs and the contention world's sweeps,
reading only their files and tables (beside ``sim`` and ``contention``, below ``runs``).

* ``files``: names, schemas, atomic writing, checked readers (``requests.csv``, ``run.json``,
  ``summary.csv``);
* ``stats``: summaries, speed-ups, β-step averages, intervals over seeds;
* ``paper``: the paper's published ratios and claims, ours beside them;
* ``report``: markdown reports and the writers of a run's folder;
* ``markdown``: the one writer of Markdown tables (the run's reports and the sweeps');
* ``sweep_report``: a contention sweep's tables, its goals' checks and its folder's writer;
* ``fidelity``: the scorecard of every published number against ours;
* ``world_bounds``, ``feasibility``: what any policy could reach in a run's world, and over a
  preset's runs;
* ``latex``: the report's tables as LaTeX files (``DataFrame.to_latex``).

The names the figures, the runs and the tests read as ``results.<name>`` are re-exported here
(``results.summarize``, ...); anything else is imported from its module.
"""


from yafs_safetail.methods.registry import (
    BASELINE_FAMILIES,
    ORACLE,
    SAFETAIL,
    baselines_of,
    parse_method,
    sort_methods,
)
from yafs_safetail.record import PHASES, REQUESTS_COLUMNS
from yafs_safetail.results.claims import check_claims
from yafs_safetail.results.files import (
    PERCENTILES,
    REQUESTS_FILE,
    RUN_FILE,
    SUMMARY_COLUMNS,
    ResultsFileError,
    file_mode,
    read_requests_csv,
    read_summary_csv,
    thin_percentiles,
    write_requests_csv,
    write_text_atomic,
)
from yafs_safetail.results.markdown import frame_markdown
from yafs_safetail.results.over_seeds import (
    aggregate_summaries,
    bootstrap_interval,
    geometric_interval,
)
from yafs_safetail.results.paper import (
    PAPER_CLAIMS,
    PAPER_RATIOS,
    PERCENTILE_NAMES,
    aggregate_speedups,
    setting_differences,
    speedup_table,
)
from yafs_safetail.results.report import (
    summary_markdown,
    write_results,
    write_summary,
)
from yafs_safetail.results.run_json import (
    CHANGED_SETTINGS_KEY,
    LEARNING_RATE_OVERRIDE_KEY,
    PLACEMENT_KEY,
    RUN_JSON_KEYS,
    TRACES_KEY,
    WORLD_OVERRIDES_KEY,
    RunMetadata,
    read_run_json,
    write_run_json,
)
from yafs_safetail.results.seed_tables import (
    aggregate_markdown,
    aggregate_table,
    comparison_markdown,
)
from yafs_safetail.results.stats import (
    abs_reward_by_episode,
    access_rate_by_episode,
    beta_averages,
    latency_deviation_by_episode,
    speedup,
    summarize,
    train_test_boundary,
)

__all__ = [
    "BASELINE_FAMILIES",
    "LEARNING_RATE_OVERRIDE_KEY",
    "ORACLE",
    "PAPER_CLAIMS",
    "PAPER_RATIOS",
    "PERCENTILES",
    "PERCENTILE_NAMES",
    "PHASES",
    "CHANGED_SETTINGS_KEY",
    "PLACEMENT_KEY",
    "REQUESTS_COLUMNS",
    "REQUESTS_FILE",
    "RUN_FILE",
    "RUN_JSON_KEYS",
    "TRACES_KEY",
    "ResultsFileError",
    "RunMetadata",
    "SAFETAIL",
    "SUMMARY_COLUMNS",
    "WORLD_OVERRIDES_KEY",
    "abs_reward_by_episode",
    "access_rate_by_episode",
    "aggregate_markdown",
    "aggregate_table",
    "aggregate_speedups",
    "aggregate_summaries",
    "baselines_of",
    "beta_averages",
    "bootstrap_interval",
    "check_claims",
    "comparison_markdown",
    "file_mode",
    "frame_markdown",
    "geometric_interval",
    "latency_deviation_by_episode",
    "parse_method",
    "read_requests_csv",
    "read_run_json",
    "read_summary_csv",
    "setting_differences",
    "sort_methods",
    "speedup",
    "speedup_table",
    "summarize",
    "summary_markdown",
    "thin_percentiles",
    "train_test_boundary",
    "write_requests_csv",
    "write_results",
    "write_run_json",
    "write_summary",
    "write_text_atomic",
]
