"""Evaluation as config, plan, run and report: the config is frozen, the plan reads and checks
every input before anything is written, the driver options are one spec list through the
driver-format registry (``--model``/``--cf-model`` deprecated aliases of ``--driver``), and
``evaluate()`` stays a thin wrapper. No SUMO run: planning starts no simulation."""

from __future__ import annotations

import ast
import inspect
import json
import textwrap
import warnings
from dataclasses import FrozenInstanceError, dataclass

import numpy as np
import pandas as pd
import pytest

from analysis.cli.main import build_parser
from analysis.errors import AnalysisError
from analysis.evaluation.config import EvaluationConfig
from analysis.evaluation.plan import DecisionStepWarning, EvaluationPlan, plan_evaluation
from irl.config import IRLConfig
from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import FEATURE_NAMES
from irl.errors import DemonstrationError, ModelFileError
from irl.result import SavedModel
from sim.closed_loop.config import ControllerConfig
from sim.drivers.callables import CallablePolicy
from sim.drivers.formats import DriverFormat, register_format, unregister_format
from sim.drivers.policy import NO_LIKELIHOOD, ConstantPolicy, PolicyDefaults, PolicyError
from sim.errors import SimError


def _model(step: float = 0.3) -> SavedModel:
    rng = np.random.default_rng(0)
    edges = MergeBins.assumed_authors()
    return SavedModel(method="qavg", theta=np.array([1.0, 0.5, -0.2]), loglik=-1.0,
                      q=rng.normal(size=(1250, 5)), config=IRLConfig(beta=1.0), domain="merge", decision_step_s=step,
                      feature_names=FEATURE_NAMES, bin_edges={k: tuple(v) for k, v in edges.to_dict().items()})


@dataclass(frozen=True)
class HalfPolicy(PolicyDefaults):
    """A driver of a format registered by this test alone (a constant action, at 0.5 s)."""

    name: str = "half"
    controls: bool = True
    source: str = ""
    decision_step_s: float = 0.5

    def probs(self, obs) -> np.ndarray:
        return np.full(N_ACTIONS, 1.0 / N_ACTIONS)

    def heldout_loglik(self, encounters, *, decision_step_s, where):
        return NO_LIKELIHOOD


@pytest.fixture
def half(tmp_path):
    register_format(DriverFormat("half-test", "half driver (this test)", load=lambda p: json.loads(p.read_text()),
                                 policy=lambda d, name, source: HalfPolicy(name=name, source=source)))
    path = tmp_path / "half.json"
    path.write_text(json.dumps({"format": "half-test/1"}))
    yield path
    unregister_format("half-test")


def rule(obs):
    """A module-level callable obs -> action (picklable)."""
    return 2


def test_the_config_is_frozen(tmp_path):
    cfg = EvaluationConfig("synthetic", 1, 0, tmp_path / "out")
    with pytest.raises(FrozenInstanceError):
        cfg.episodes = 3  # type: ignore[misc]
    assert cfg.workers is None and cfg.executor is None  # one default: every core, as the CLI's


def test_the_plan_is_an_inspectable_frozen_object_and_writes_nothing(tmp_path, half):
    out = tmp_path / "out"
    cfg = EvaluationConfig("synthetic", 2, 0, out, drivers=(_model(), half, "idm", rule, ConstantPolicy(0)),
                           baselines=("sumo",), executor="serial")
    with pytest.warns(DecisionStepWarning, match="half was trained at 0.5 s"), \
            pytest.warns(UserWarning, match="idm without training encounters"):
        plan = plan_evaluation(cfg)
    assert isinstance(plan, EvaluationPlan) and plan.config is cfg and plan.out_dir == out
    # models first, then the baselines (a baseline spec added to them), then the other drivers in order
    assert [p.name for p in plan.policies] == ["qavg", "sumo", "idm", "half", "rule", "constant-high-brake"]
    assert plan.baselines == ("sumo", "idm")
    assert plan.controller.decision_step_s == 0.3  # the model's step, fixed for every driver
    assert plan.executor == "serial" and plan.scores == dict.fromkeys(plan.scores)  # no demos: no scores
    assert isinstance(plan.policies[4], CallablePolicy)
    assert plan.provenance["models"]["half"]["path"].endswith("half.json")
    with pytest.raises(FrozenInstanceError):
        plan.executor = "process"  # type: ignore[misc]
    assert not out.exists()


def test_the_executor_is_resolved_once_in_the_plan(tmp_path):
    plan = plan_evaluation(EvaluationConfig("synthetic", 1, 0, tmp_path / "o", baselines=("sumo",), workers=1))
    assert plan.executor == "process:1"
    assert plan_evaluation(EvaluationConfig("synthetic", 1, 0, tmp_path / "o", baselines=("sumo",))).executor == "process"


def _missing_columns() -> pd.DataFrame:
    return pd.DataFrame({"encounter_id": [0, 0], "Frame_ID": [0, 1]})


HOSTILE = {
    "no episodes": (dict(episodes=0), AnalysisError, "episodes must be >= 1"),
    "unknown scenario": (dict(scenario="no-such-scenario"), Exception, "no-such-scenario"),
    "implausible duration": (dict(duration_s=-5.0), Exception, "duration"),
    "unknown baseline": (dict(baselines=("human",)), SimError, "human"),
    "bad decision step": (dict(controller=ControllerConfig(decision_step_s=0.15)), AnalysisError, "multiple"),
    "missing model file": (dict(drivers=("nope.json",)), ModelFileError, "nope.json"),
    "a lambda for worker processes": (dict(drivers=(lambda obs: 2,), executor="process:1"), PolicyError,
                                      "cannot be sent to the worker"),
    "a driver named as a baseline": (dict(drivers=(ConstantPolicy(0, name="sumo"),)), PolicyError, "also the baseline"),
    "an executor that does not parse": (dict(executor="process:0"), AnalysisError, "process"),
    "held-out table without columns": (dict(demos=_missing_columns()), DemonstrationError, "lacks column"),
    "not a policy": (dict(drivers=(object(),)), PolicyError, "object"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_the_plan_refuses_bad_input_before_any_output_folder_exists(tmp_path, case):
    kw, error, match = HOSTILE[case]
    out = tmp_path / "deep" / "out"
    base = dict(scenario="synthetic", episodes=1, seed=0, out_dir=out, baselines=("sumo",))
    with pytest.raises(error, match=match):
        plan_evaluation(EvaluationConfig(**{**base, **kw}))
    assert not (tmp_path / "deep").exists()


def _args(*argv: str):
    return build_parser().parse_args(["evaluate", *argv])


@pytest.mark.parametrize("alias", ["--model", "--cf-model"])
def test_the_aliases_say_they_are_deprecated_and_plan_as_driver(tmp_path, half, alias, capsys):
    from analysis.cli.commands.evaluate import evaluation_config

    model = _model().save(tmp_path / "qavg.json")
    common = ["--baselines", "sumo", "--executor", "serial", "--out", str(tmp_path / "o")]
    with pytest.warns(DeprecationWarning, match="--driver"):
        old = _args(alias, str(model), alias, str(half), *common)
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"merge-irl evaluate: warning: {alias} is deprecated and goes in the next release: use --driver "
                   "(the same meaning)"]  # once
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        new = _args("--driver", str(model), "--driver", str(half), *common)
    assert capsys.readouterr().err == ""
    with pytest.warns(DecisionStepWarning):
        a = plan_evaluation(evaluation_config(old))
    with pytest.warns(DecisionStepWarning):
        b = plan_evaluation(evaluation_config(new))
    assert a.config == b.config and a.controller == b.controller and a.baselines == b.baselines
    assert [(type(p), p.name, p.source) for p in a.policies] == [(type(p), p.name, p.source) for p in b.policies]
    assert a.provenance == b.provenance  # the same files read
    assert [p.name for p in a.policies] == ["qavg", "sumo", "half"]  # --cf-model through the driver-format registry


def test_a_baseline_name_is_a_driver_spec_on_the_command_line(tmp_path):
    from analysis.cli.commands.evaluate import evaluation_config

    plan = plan_evaluation(evaluation_config(_args("--driver", "uniform", "--baselines", "sumo", "--executor",
                                                   "serial", "--out", str(tmp_path / "o"))))
    assert [p.name for p in plan.policies] == ["sumo", "uniform"] and plan.baselines == ("sumo", "uniform")


def test_evaluate_is_a_thin_wrapper():
    from analysis.evaluation import evaluate as module

    tree = ast.parse(textwrap.dedent(inspect.getsource(module)))
    fn = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "evaluate")
    lines = fn.end_lineno - fn.lineno + 1  # type: ignore[operator]
    assert lines <= 60, f"evaluate() is {lines} lines; its work belongs in config, plan, run and outcome"
    assert inspect.signature(module.evaluate).parameters["workers"].default is None


def test_one_driver_given_alone_is_a_list_of_one():
    """drivers="x.json" is one spec, not its characters; a list becomes a tuple."""
    assert EvaluationConfig("synthetic", 1, 1, "out", drivers="x.json").drivers == ("x.json",)
    assert EvaluationConfig("synthetic", 1, 1, "out", drivers=["a.json", "idm"]).drivers == ("a.json", "idm")


def test_a_misspelt_baseline_is_named_as_neither_file_nor_baseline(tmp_path, monkeypatch):
    """--driver IDM: not 'no such file' but what it could have been, the baselines listed."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ModelFileError, match=r"--driver IDM: neither a file nor a baseline name \(baselines: .*idm"):
        plan_evaluation(EvaluationConfig("synthetic", 1, 1, tmp_path / "out", drivers=("IDM",)))
    assert not (tmp_path / "out").exists()
