"""Metrics, paper tables, plots, sweeps, rerun logs, and the ``merge-irl`` command line."""
