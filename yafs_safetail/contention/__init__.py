"""The contention world and its engine: many users at once, sharing the edge servers (beyond the paper).

It serves the contention world alone, with its own event engine (not the YAFS core); the sweeps
over it are campaigns (``runs.sweep``, ``runs.sweep_config``), their reports ``results.sweep_report``.

``engine`` runs the event loop of ``simulation`` (processor-sharing servers, refusal or FIFO
queues, cancellation, hedged and tied dispatch; no edge knowledge) over the objects of ``state``,
``types`` is what it takes and gives, ``world`` builds its inputs from the traces and topology
(``config``: the run's settings, arrivals CSV and users' conditions), ``run`` drives any Policy
through it, ``queueing`` the stripped configuration checked against M/M/1 results, ``env`` the world as a Gymnasium environment (``yafs_safetail/SafeTailContention-v0``).
docs/contention.md describes the model and its measured behaviour.
"""
