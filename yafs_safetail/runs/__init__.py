"""Whole runs: the configuration (config), the world recipe, the experiment, campaigns and their
engines, calibration and the learning-rate rule (docs/architecture.md). Importing the package
imports none of them."""
