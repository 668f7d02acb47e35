"""Adding an IRL method is one registration: a toy method registered from this test alone runs
through ``irl.fit.fit``, ``learn``'s model files, the closed-loop ``evaluate`` (real SUMO) and
``reproduce`` (the authors' gridworld data), and is labelled from the registry."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from irl.boltzmann import log_policy
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, ModelFileError
from irl.fit import Method, fit, method_names, register
from irl.methods.registry import unregister
from irl.result import FitResult, SavedModel

TOY_THETA = 0.25


def fit_toy(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *, theta0=None,
            progress: bool = False) -> FitResult:
    """Every weight TOY_THETA, Q = R = phi . theta: the smallest honest method."""
    theta = np.full(demos.n_features, TOY_THETA)
    q = demos.features @ theta
    lp = log_policy(q, config.beta)
    states, actions, _ = demos.flat()
    ll = float(lp[states, actions].sum())
    return FitResult(method="toy", theta=theta, loglik=ll, q=q, config=config, loglik_trace=np.array([ll]),
                     theta_trace=theta[None, :], converged=True, message="toy")


@pytest.fixture
def toy():
    register(Method("toy", "Toy", fit_toy, cost=5))
    yield
    unregister("toy")


def _encounters(n=200, seed=1) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n // 20), 20), "Frame_ID": np.arange(n),
        "d_AC": rng.uniform(10, 200, n), "d_AB": rng.uniform(-20, 120, n), "v_AC": rng.normal(0, 5, n),
        "v_AB": rng.normal(0, 5, n), "B_is_truck": rng.random(n) < 0.2, "acc_A": rng.normal(0, 4, n),
    })


def test_a_registered_method_is_listed_fitted_and_its_model_files_load(toy, tmp_path):
    from analysis.experiments.learn import fit_problem, saved_model
    from irl.problems import load_problem

    assert method_names()[-1] == "toy"
    path = tmp_path / "enc.parquet"
    _encounters().to_parquet(path)
    problem = load_problem("merge", path, decision_step_s=0.1)
    res = fit_problem(problem, "toy", IRLConfig(beta=1.0), seed=0)
    assert res.method == "toy" and np.all(res.theta == TOY_THETA) and np.isfinite(res.loglik)
    direct = fit("toy", problem.demos, IRLConfig(beta=1.0), np.random.default_rng(0))
    assert direct.loglik == res.loglik
    out = saved_model(res, problem, seed=0).save(tmp_path / "toy.json")
    assert SavedModel.load(out).method == "toy"
    unregister("toy")  # a model file of a method nobody registered is refused, with the list
    with pytest.raises(ModelFileError, match=r"toy\.json: method: must be one of \(.*\), got 'toy'"):
        SavedModel.load(out)
    register(Method("toy", "Toy", fit_toy))


def test_registering_twice_or_without_a_name_is_refused(toy):
    with pytest.raises(ConfigError, match="registered already"):
        register(Method("toy", "Toy", fit_toy))
    with pytest.raises(ConfigError, match="needs a name"):
        register(Method(" ", "blank", fit_toy))
    with pytest.raises(ConfigError, match="does not name an importable object"):
        fit_with_bad_ref()


def fit_with_bad_ref():
    register(Method("bad-ref", "Bad", "irl.nowhere:fit_bad"))
    try:
        t = Demonstrations(states=(np.array([0]),), actions=(np.array([0]),), features=np.zeros((1, 1, 1)),
                           n_states=1, n_actions=1)
        fit("bad-ref", t, IRLConfig(), np.random.default_rng(0))
    finally:
        unregister("bad-ref")


@pytest.mark.sumo
def test_a_registered_method_drives_in_evaluate(toy, tmp_path):
    from analysis.evaluation.evaluate import evaluate
    from analysis.experiments.learn import fit_problem, saved_model
    from irl.problems import load_problem

    path = tmp_path / "enc.parquet"
    _encounters().to_parquet(path)
    problem = load_problem("merge", path, decision_step_s=0.1)
    model = saved_model(fit_problem(problem, "toy", IRLConfig(beta=1.0), seed=0), problem, seed=0)
    model_path = model.save(tmp_path / "models" / "toy.json")
    rep = evaluate([model_path], "synthetic", 1, 3, tmp_path / "out", duration_s=110.0, demos=_encounters(60, 2),
                   baselines=("uniform",), workers=1, rrd=False, progress=False)
    assert list(rep.aggregates) == ["toy", "uniform"]
    data = json.loads(rep.metrics_json.read_text())
    assert np.isfinite(data["policies"]["toy"]["aggregate"]["heldout_loglik_per_step"])


def test_a_registered_method_runs_through_reproduce(toy, railusm):
    from analysis.experiments.reproduce import ReproduceConfig, reproduce
    from analysis.experiments.reproduce_report import format_report

    rep = reproduce(1, ReproduceConfig(railusm, trials=1, methods=("toy",), holdout=False, executor="serial"))
    toy_rows = [r for r in rep.rows if r.method == "toy"]
    assert len(toy_rows) == 1 and np.allclose(toy_rows[0].theta_mean, TOY_THETA)
    assert "Toy" in format_report(rep)
