"""The baseline registry: one dict (name -> Baseline) replaces the lists; a baseline registered
from outside the package runs through evaluate with its held-out score (real SUMO, short)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from sim.drivers.baselines import (
    BASELINES,
    Baseline,
    BaselineContext,
    baseline_drivers,
    default_baselines,
    register_baseline,
)
from sim.drivers.policy import ConstantPolicy, PolicyError
from sim.errors import SimError


@pytest.fixture
def always_zero():
    """The toy baseline ``always-zero`` (always the Zero action), registered for one test."""
    b = register_baseline(Baseline("always-zero", lambda ctx: ConstantPolicy(2, name="always-zero"),
                                   help="always the Zero action"))
    yield b
    BASELINES.pop(b.name)


@pytest.fixture
def fitted_toy():
    b = register_baseline(Baseline("toy-fitted", lambda ctx: ConstantPolicy(2, name="toy-fitted"), fitted=True))
    yield b
    BASELINES.pop(b.name)


def test_the_default_set_and_order_are_unchanged():
    assert default_baselines() == ("sumo", "uniform", "marginal", "markov", "bc")
    assert list(BASELINES) == ["sumo", "uniform", "marginal", "markov", "bc", "idm", "sumo-in-lane"]
    assert [n for n, b in BASELINES.items() if b.fitted] == ["marginal", "markov", "bc"]
    assert all(b.help for b in BASELINES.values())


def test_the_command_lines_default_is_the_registrys():
    from analysis.cli.main import build_parser

    args = build_parser().parse_args(["evaluate"])
    assert tuple(args.baselines.split(",")) == default_baselines()


def test_a_name_is_registered_once(always_zero):
    with pytest.raises(PolicyError, match="'always-zero' is registered already"):
        register_baseline(always_zero)


def test_unknown_names_are_refused_with_the_known_ones(always_zero):
    with pytest.raises(SimError, match=r"unknown baseline\(s\) \['nope'\]; expected some of .*sumo-in-lane, always-zero"):
        baseline_drivers(["nope"], None, None, None, 0.3)


def test_a_fitted_baseline_is_left_out_without_training_encounters(fitted_toy, always_zero):
    pols = baseline_drivers(["toy-fitted", "always-zero", "uniform"], None, None, None, 0.3)
    assert [p.name for p in pols] == ["always-zero", "uniform"]


def test_a_factory_must_name_its_policy_as_its_baseline():
    register_baseline(Baseline("misnamed", lambda ctx: ConstantPolicy(2)))
    try:
        with pytest.raises(PolicyError, match="baseline 'misnamed': its factory made a policy named 'constant-zero'"):
            baseline_drivers(["misnamed"], None, None, None, 0.3)
    finally:
        BASELINES.pop("misnamed")


def test_the_context_reads_the_training_encounters_only_when_asked():
    ctx = BaselineContext(None, 0.3, pd.DataFrame({"x": [1.0]}))  # not an encounter table
    assert ctx.where == "training encounters"
    from irl.errors import DemonstrationError

    with pytest.raises(DemonstrationError, match="lacks column"):
        _ = ctx.action_acc_ft_s2
    assert len(BaselineContext(None, 0.3).action_acc_ft_s2) == 5  # no training: the bins' midpoints


def _zero_encounters(n=60) -> pd.DataFrame:
    rng = np.random.default_rng(3)
    return pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n // 10), 10), "Frame_ID": np.arange(n),
        "d_AC": rng.uniform(10, 200, n), "d_AB": rng.uniform(-20, 120, n), "v_AC": rng.normal(0, 5, n),
        "v_AB": rng.normal(0, 5, n), "B_is_truck": False, "acc_A": np.zeros(n),  # every decision Zero
    })


@pytest.mark.sumo
def test_a_registered_baseline_runs_through_evaluate_with_its_heldout_score(tmp_path, always_zero):
    from analysis.evaluation.evaluate import evaluate
    from analysis.evaluation.heldout_scoring import load_heldout

    demos = _zero_encounters()
    rep = evaluate([], "synthetic", 1, 3, tmp_path / "out", duration_s=100.0, demos=demos,
                   baselines=("uniform", "always-zero"), workers=1, rrd=False, progress=False)
    assert list(rep.aggregates) == ["uniform", "always-zero"]
    assert rep.aggregates["always-zero"].n_decisions > 0  # it drove A
    expected = ConstantPolicy(2, name="always-zero").heldout_loglik(
        load_heldout(demos).encounters, decision_step_s=0.3, where="test")
    assert expected[0] == 0.0 and expected[1] == 0.0  # every held-out decision is Zero: log 1
    data = json.loads(rep.metrics_json.read_text())
    agg = data["policies"]["always-zero"]["aggregate"]
    assert agg["heldout_loglik"] == expected[0] and agg["heldout_loglik_per_step"] == expected[1]
    assert data["policies"]["uniform"]["aggregate"]["heldout_loglik_per_step"] == pytest.approx(np.log(0.2))
    assert "| always-zero | 1 |" in rep.report_md.read_text()
