"""Whole runs and campaigns: the experiment, campaigns and their engines, the contention sweeps
(each point a campaign run) and the training mechanism, calibration and the learning-rate rule.

They serve both worlds: the paper's single-user world through the YAFS core (``sim``) and the
contention world through its engine (``contention``); a run's settings are ``settings``' and its
world ``worlds.recipe``'s (docs/architecture.md). Importing the package imports none of them."""
