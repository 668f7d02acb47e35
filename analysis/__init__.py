"""Metrics, paper tables, plots, sweeps, rerun logs, and the ``merge-irl`` command line."""

from merge_irl.moved import install as _install_moved_paths

_install_moved_paths()  # old import paths (analysis.rrd_read, ...) fail naming their new home
