"""The contention world: many users at once, sharing the edge servers (beyond the paper).

``engine`` runs the event loop of ``simulation`` (processor-sharing servers, refusal or FIFO
queues, cancellation, hedged and tied dispatch; no edge knowledge) over the objects of ``state``,
``types`` is what it takes and gives, ``world`` builds its inputs from the traces and topology
(``config``: the run's settings, arrivals CSV and users' conditions), ``run`` drives any Policy
through it, ``sweep`` runs the load and failure sweeps (``sweep_config``: what a sweep is, light
for the commands' options), ``queueing`` the stripped configuration checked against M/M/1
results, ``env`` the world as a Gymnasium environment (``yafs_safetail/SafeTailContention-v0``).
docs/contention.md describes the model and its measured behaviour.
"""
