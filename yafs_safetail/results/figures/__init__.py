"""Figures drawn from results folders (or a run's tables in memory), never from the simulator.

* ``run_figures``: one run's figures, the paper's Figs. 5-7 (a)-(g), ``p99_vs_energy`` and
  ``latency_cdf`` (``yafs-safetail figures DIR`` redraws them);
* ``multiseed``: one use case and preset over seeds, with 95% bootstrap bands (REPORT.md);
* ``sweeps``: a contention sweep's figures from its table (``results.sweep_report`` writes them);
* ``mechanism``, ``fidelity``, ``compare``: the training mechanism's figure, the fidelity
  scorecard's and two runs side by side (``runs.mechanism``, ``results.fidelity`` and
  ``results.compare`` compute their tables and re-export them);
* ``style``: what both share: matplotlib's style, each method's colour, the files' writing.

Each module imports matplotlib (sweeps, mechanism, fidelity and compare only when drawing, so
the modules that re-export them stay light); this package itself imports nothing.
"""
