"""Run a use case, read its results and plot them from Python, in a few stable calls.

The command line (``yafs-safetail run``) and this module run the same experiment
(``runs.experiment.run_experiment``) and write the same results folder; this module is the
entry for notebooks and scripts::

    from yafs_safetail import api

    folder = api.run(1, steps_scale=0.02, seed=0)          # UC1 at 2% of the paper's budget
    results = api.read_results(folder)                     # summary, requests, run.json
    results.summary[["method", "p50_s", "p99_s"]]
    api.paper_figures(results)["a"]                        # the paper's panel (a)
    api.latency_cdf(results)                               # every method's latency CDF

Every function raises a ``ValueError`` subclass with one line naming the setting, file or
field and what is wrong; nothing is written before a run's checks pass, and a run replaces
only an earlier results folder, and that only with ``overwrite=True``. Importing this module
loads nothing heavy (NumPy, pandas, matplotlib and TensorFlow load on the first call that needs
them), so ``from yafs_safetail import api`` answers at once. docs/python_api.md documents it.
"""

from yafs_safetail.api.drawing import PAPER_PANELS, latency_cdf, paper_figures
from yafs_safetail.api.reading import COMPARED_METRICS, RunResults, compare_over_seeds, read_results
from yafs_safetail.api.running import SETTINGS, ApiError, _user_method, run

__all__ = ["ApiError", "RunResults", "run", "read_results", "paper_figures", "latency_cdf",
           "compare_over_seeds", "SETTINGS", "PAPER_PANELS", "COMPARED_METRICS", "_user_method"]
