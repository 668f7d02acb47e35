"""The exceptions of ``analysis``: :class:`AnalysisError`, raised by the jobs (evaluation,
experiments, the demo, recordings, sweeps and the command line) for a bad input or a failed run.

It is a :class:`sim.errors.SimError`, so code that catches SimError around a job still catches
it, and the command line reports it as one line with exit status 2 (``analysis.cli.main``)."""

from __future__ import annotations

from sim.errors import SimError


class AnalysisError(SimError):
    """Base class of the errors raised by the ``analysis`` package itself (a bad option or input
    of a job, or runs of a sweep that failed); every message names what is at fault."""
