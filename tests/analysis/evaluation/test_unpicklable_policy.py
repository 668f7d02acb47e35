"""A policy the evaluation's worker processes cannot receive (a lambda, a closure holding a lock,
an object holding an open file) is refused before any work, naming the policy, why workers need
it pickled and the fix; the same lambda runs in this process with ``executor="serial"``."""

from __future__ import annotations

import threading

import pytest

from analysis.evaluation.evaluate import evaluate
from analysis.evaluation.policies import check_picklable
from sim.drivers.callables import CallablePolicy
from sim.drivers.policy import PolicyError


def _closure_with_lock():
    lock = threading.Lock()

    def keep_lane(obs):
        with lock:
            return 2
    return keep_lane


class _Logger:
    """A predict object that logs to an open file."""

    def __init__(self, path):
        self.log = open(path, "w")  # noqa: SIM115 - held open on purpose

    def __call__(self, obs):
        self.log.write("x\n")
        return 2


def _unpicklable(tmp_path):
    return [CallablePolicy(lambda obs: 2, name="lam"), CallablePolicy(_closure_with_lock(), name="locked"),
            CallablePolicy(_Logger(tmp_path / "log.txt"), name="logger")]


def test_unpicklable_policies_refused_before_any_work(tmp_path) -> None:
    for pol in _unpicklable(tmp_path):
        out = tmp_path / f"ev-{pol.name}"
        with pytest.raises(PolicyError) as e:
            evaluate([], "synthetic", 1, 0, out, duration_s=90, baselines=[], policies=[pol], rrd=False,
                     progress=False, executor="process:1")
        msg = str(e.value)
        assert "\n" not in msg
        assert f"policy {pol.name!r} cannot be sent to the worker processes of --executor process:1" in msg
        assert "receive each policy pickled" in msg and "module-level function" in msg
        assert "--executor serial" in msg
        assert not out.exists()  # refused before the output folder is made


def test_cloudpickle_under_dask_takes_a_lambda_not_a_lock(tmp_path) -> None:
    pytest.importorskip("cloudpickle")
    lam, locked, logger = _unpicklable(tmp_path)
    check_picklable([lam], "dask-local:1")  # cloudpickle pickles lambdas
    for pol in (locked, logger):
        with pytest.raises(PolicyError, match=f"policy '{pol.name}' cannot be sent .*dask-local:1"):
            check_picklable([pol], "dask-local:1")
    check_picklable([lam, locked, logger], "serial")  # nothing is pickled in this process


@pytest.mark.sumo
def test_the_lambda_runs_serially(tmp_path) -> None:
    rep = evaluate([], "synthetic", 1, 3, tmp_path / "ev", duration_s=90, baselines=[],
                   policies=[CallablePolicy(lambda obs: 2, name="lam")], rrd=False, progress=False,
                   executor="serial")
    assert rep.aggregates["lam"].n_decisions > 0
