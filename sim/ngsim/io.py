"""NGSIM file input/output: the public entry points.

* :func:`~sim.ngsim.read.read_ngsim` -- stream an NGSIM ``trajectories-*.csv`` / ``.txt`` file into the
  trajectory table, validated, with a report of the defects found (:mod:`sim.ngsim.read`).
* :func:`~sim.ngsim.write.write_ngsim_csv` -- write a trajectory table in NGSIM's exact CSV format
  (:mod:`sim.ngsim.write`).
* :func:`~sim.ngsim.read.read_trajectories` -- a trajectory table from Parquet or an NGSIM file, by suffix
  (what commands taking "a trajectory file" call).
"""

from sim.ngsim.read import read_ngsim, read_trajectories
from sim.ngsim.write import write_ngsim_csv

__all__ = ["read_ngsim", "read_trajectories", "write_ngsim_csv"]
