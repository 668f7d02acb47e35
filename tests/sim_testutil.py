"""Shared helpers of the sim/encounter tests: one short real SUMO run per test module."""

from __future__ import annotations

import os
from contextlib import contextmanager

from scenarios.loader import load_scenario
from sim.runtime.run import run_scenario
from sim.runtime.run_result import SimulationResult


@contextmanager
def cache_env(path):
    old = os.environ.get("MERGE_IRL_CACHE")
    os.environ["MERGE_IRL_CACHE"] = str(path)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MERGE_IRL_CACHE", None)
        else:
            os.environ["MERGE_IRL_CACHE"] = old


def short_run(cache_dir, *, scenario="synthetic", seed=None, duration_s=150.0, hooks=()) -> SimulationResult:
    """A short real run (default: synthetic, 150 s with its 60 s warm-up)."""
    with cache_env(cache_dir):
        return run_scenario(load_scenario(scenario), seed=seed, duration_s=duration_s, hooks=hooks)


def default_sigint() -> None:
    """``preexec_fn`` of a child that a test interrupts with SIGINT, as Ctrl-C in a terminal would.

    A job started in the background by a non-interactive shell (CI runners, ``cmd &``) inherits
    SIGINT *ignored*, and Python then installs no KeyboardInterrupt handler: restore the default.
    """
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
