"""Policies both ways (sim.drivers.callables): any callable obs -> action as a closed-loop driver,
and every learned model file as a callable obs -> action index."""

from __future__ import annotations

import math
import pickle
import sys

import numpy as np
import pytest
from irl_testdata import planning_encounters

from analysis.evaluation.policies import learned_policy
from irl.config import IRLConfig
from irl.domains.merge.actions import ACTION_ACC_FT_S2, action_of
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.car_following import CF_FEATURES
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.domains.merge.features import FEATURE_NAMES
from irl.errors import ModelFileError
from irl.result import SavedModel
from merge_irl.units import FT_PER_M
from sim.drivers.callables import TRUCK_MIN_LENGTH_FT, CallablePolicy, PolicyCallable
from sim.drivers.callables.actions import parse_action
from sim.drivers.callables.specs import load_callable, parse_spec
from sim.drivers.formats import policy_callable
from sim.drivers.observe import CONTINUOUS_NAMES, CONTINUOUS_UNITS, MergeObservation
from sim.drivers.policy import PolicyError, check_policy

OBS = MergeObservation(120.0, 30.0, 4.0, -2.0, False, speed_A=55.0, len_C=15.0, len_B=16.0)


def test_actions_accepted_and_refused() -> None:
    assert parse_action(3) == 3 and parse_action(np.int64(0)) == 0 and parse_action(np.array(4)) == 4
    assert parse_action(np.array([2], dtype=np.int32)) == 2  # SB3's predict on a Discrete space, batched
    assert parse_action(-1.5) == -1.5 and parse_action(np.float32(0.5)) == 0.5
    assert parse_action(np.array([1.25], dtype=np.float32)) == 1.25  # SB3's predict on a Box(1,)
    assert isinstance(parse_action(np.array([2.0])), float)  # a float is an acceleration, never an index
    for bad, said in ((5, "returned action 5"), (-1, "returned action -1"), (True, "bool"),
                      ((1, None), r"predict\(\) result"), (np.array([1, 2]), r"shape \(2,\)"),
                      (math.nan, "finite"), (1e6, "beyond any road vehicle"), (-25.0, "beyond any road vehicle"),
                      (np.array(["a"]), "dtype"), ("2", "str"), (None, "NoneType"),
                      (object(), "object")):
        with pytest.raises(PolicyError, match=said):
            parse_action(bad, where="policy 'x'")


def test_continuous_and_discrete_callables_drive_as_the_controller_asks() -> None:
    assert CONTINUOUS_NAMES == ("d_AC", "v_AC", "d_AB", "v_AB", "v_A", "len_C", "len_B")
    assert len(CONTINUOUS_UNITS) == len(CONTINUOUS_NAMES)
    seen = []

    def brake(obs):
        seen.append(obs)
        return -1.0  # m/s^2: -3.3 ft/s^2, Low Brake

    p = CallablePolicy(brake)
    check_policy(p)
    assert p.name == "brake" and p.decision_step_s is None and p.controls
    acc_ft = -1.0 * FT_PER_M
    probs = p.probs(OBS)
    assert probs.tolist() == [0.0, 1.0, 0.0, 0.0, 0.0] and action_of(acc_ft) == 1
    assert p.acceleration(OBS, 1) == pytest.approx(acc_ft)
    assert p.acceleration(OBS, 0) == ACTION_ACC_FT_S2[0]  # another bin (a safety filter's): its midpoint
    assert len(seen) == 1  # one call per observation
    np.testing.assert_array_equal(seen[0], OBS.continuous()[0])
    assert seen[0].shape == (7,) and seen[0].dtype == np.float64
    d = CallablePolicy(lambda obs: np.int64(3), name="idx", action_acc_ft_s2=(-10, -3, 0, 3, 10))
    assert d.probs(OBS).tolist() == [0, 0, 0, 1, 0] and d.acceleration(OBS, 3) == 3.0
    assert all(math.isnan(v) for v in d.heldout_loglik(None, decision_step_s=0.3, where="x"))  # no likelihood

    class Sb3Like:  # Stable-Baselines3's predict: (action [1], state)
        def predict(self, obs, deterministic=False):
            assert deterministic is True
            return np.array([0]), None

    assert CallablePolicy(Sb3Like()).probs(OBS).tolist() == [1, 0, 0, 0, 0]
    with pytest.raises(PolicyError, match="policy 'oops'.*returned action 7"):
        CallablePolicy(lambda obs: 7, name="oops").probs(OBS)
    with pytest.raises(PolicyError, match="policy 'boom'.*raised ZeroDivisionError"):
        CallablePolicy(lambda obs: 1 / 0, name="boom").probs(OBS)
    with pytest.raises(PolicyError, match="not callable"):
        CallablePolicy(3)


RULE = "def rule(obs):\n    return 0 if obs[0] < 50 else 2\n\nclass Holder:\n    def predict(self, obs, deterministic=False):\n" \
       "        return 4, None\n\nholder = Holder()\n"


def test_specs_load_and_pickle_as_their_spec(tmp_path, monkeypatch) -> None:
    f = tmp_path / "my_rules.py"
    f.write_text(RULE)
    p = CallablePolicy.from_spec(f"{f}:rule")
    assert p.name == "rule" and p.source == str(f.resolve()) and p.spec == f"{f.resolve()}:rule:rule"
    assert p.probs(OBS).tolist() == [0, 0, 1, 0, 0]
    # pickled as its spec: a fresh process imports the file again, nothing of the function is pickled
    blob = pickle.dumps(p)
    assert b"my_rules.py:rule" in blob
    back = pickle.loads(blob)
    assert back == p and back.probs(OBS).tolist() == [0, 0, 1, 0, 0]
    assert CallablePolicy.from_spec(f"{f}:holder").probs(OBS).tolist() == [0, 0, 0, 0, 1]  # through its predict
    with pytest.raises(PolicyError, match=r"returned tuple \(4, None\).*give the object"):
        CallablePolicy.from_spec(f"{f}:holder.predict:h").probs(OBS)  # the method itself: a clear hint
    # a dotted module on sys.path; the name part names the row
    monkeypatch.syspath_prepend(str(tmp_path))
    q = CallablePolicy.from_spec("my_rules:rule:near-brake")
    assert q.name == "near-brake" and q.source == sys.modules["my_rules"].__file__
    assert pickle.loads(pickle.dumps(q)).name == "near-brake"
    # renamed (evaluate numbers repeated names) and still pickled by spec
    from analysis.evaluation.policies import with_distinct_names

    a, b = with_distinct_names([p, CallablePolicy.from_spec(f"{f}:rule")])
    assert (a.name, b.name) == ("rule-1", "rule-2") and pickle.loads(pickle.dumps(b)).name == "rule-2"
    for spec, said in (("a", "module:callable"), (f"{tmp_path / 'x.py'}:f", "no such file"),
                       (f"{f}:nope", "no attribute"), ("1bad:f", "neither a dotted"), (f"{f}:a-b", "not a Python name")):
        with pytest.raises(PolicyError, match=said):
            load_callable(spec)
    assert parse_spec(f"{f}:rule:x").is_file and not parse_spec("pkg.mod:f").is_file


def _tabular(tmp_path):
    rng = np.random.default_rng(3)
    edges = MergeBins.assumed_authors()
    m = SavedModel(method="qavg", theta=np.array([1.0, 0.5, -0.2]), loglik=-1.0, q=rng.normal(size=(1250, 5)) * 3,
                   config=IRLConfig(beta=1.0), domain="merge", feature_names=FEATURE_NAMES,
                   bin_edges={k: tuple(v) for k, v in edges.to_dict().items()})
    return m.save(tmp_path / "qavg.json")


def test_every_learned_model_file_is_a_policy_callable(tmp_path) -> None:
    from irl.planning.decisions import encounter_decisions
    from irl.planning.driver import learn_planning_driver
    from irl.planning.model import PlannerConfig

    rng = np.random.default_rng(0)
    obs = np.column_stack([rng.uniform(20, 250, 40), rng.normal(0, 5, 40), rng.uniform(-50, 120, 40),
                           rng.normal(0, 5, 40), rng.uniform(20, 80, 40), np.full(40, 15.0), np.full(40, 15.0)])
    obs[:5, :2] = obs[:5, 5] = np.nan  # no lead car
    obs[5:10, 6] = 40.0  # B a truck
    # tabular: the model's own bins, the truck flag from B's length
    path = _tabular(tmp_path)
    pol = learned_policy(path)
    fn = policy_callable(path)
    for x in obs:
        truck = bool(x[6] >= TRUCK_MIN_LENGTH_FT)
        s = pol.encoder.state(x[0], x[2], x[1], x[3], truck)
        assert fn(x) == int(np.argmax(pol.log_pi[s]))
    assert any(pol.encoder.state(x[0], x[2], x[1], x[3], True) != pol.encoder.state(x[0], x[2], x[1], x[3], False)
               for x in obs[5:10])
    # car-following logit: A's previous action is the callable's last one, reset() forgets it
    theta = np.zeros(len(CF_FEATURES))
    theta[CF_FEATURES.index("keep_action")] = 5.0
    theta[CF_FEATURES.index("bias_high_brake")] = 1.0
    cf = CarFollowingLogit(theta, (-12.0, -3.0, 0.0, 3.0, 8.0), 0.3)
    cf_fn = policy_callable(cf.save(tmp_path / "cf.json"))
    first = cf_fn(obs[20])
    assert [cf_fn(x) for x in obs[21:25]] == [first] * 4  # keeps its action
    cf_fn.reset()
    assert cf_fn(obs[20]) == first
    want = np.exp(cf.log_policy(obs[20:21], np.array([-1])))[0]
    assert first == int(np.argmax(want))
    # planning driver: prev acceleration unknown (0) and C's acceleration 0 at the first decision
    d = encounter_decisions(planning_encounters(n=6))
    drv = learn_planning_driver(d, selection=PlannerConfig(grid="g13", horizon_s=0.9))
    pl_fn = policy_callable(drv.save(tmp_path / "planner.json"))
    x = obs[30]
    # it decides by its fitted rule (the most likely fine acceleration's bin), with mode or not
    assert pl_fn(x) == action_of(float(drv.act(x[None], np.array([0.0]), np.array([0.0]))[0]))
    assert policy_callable(drv.save(tmp_path / "planner.json"), mode=False, seed=3)(x) == pl_fn.__class__(
        pl_fn.policy)(x)
    assert pl_fn(obs[31:32]) in range(5)  # [1, 7] too
    # sampled with its own generator: reproducible
    s1 = [PolicyCallable(pol, mode=False, seed=7)(x) for x in obs]
    assert s1 == [PolicyCallable(pol, mode=False, seed=7)(x) for x in obs]
    with pytest.raises(PolicyError, match="7 numbers"):
        fn(np.zeros(5))
    with pytest.raises(ModelFileError):
        policy_callable(tmp_path / "none.json")


def test_the_adapters_are_named_by_direction_and_the_old_names_still_work() -> None:
    import sim.drivers.callables as callables
    from sim.drivers.callables.adapters import CallableFromDriver, DriverFromCallable
    from sim.drivers.policy import ConstantPolicy, Driver, Policy

    assert callables.CallablePolicy is DriverFromCallable and callables.PolicyCallable is CallableFromDriver
    assert Policy is Driver
    d = DriverFromCallable(lambda obs: 3, name="three")
    assert isinstance(d, Driver) and d.probs(OBS).tolist() == [0, 0, 0, 1, 0]
    assert CallableFromDriver(ConstantPolicy(1))(np.zeros(7)) == 1


def test_the_old_callable_module_paths_name_their_new_home() -> None:
    for old, new in [("callable_actions", "actions"), ("callable_limits", "limits"), ("callable_specs", "specs")]:
        with pytest.raises(ModuleNotFoundError, match=rf"sim\.drivers\.{old} moved to sim\.drivers\.callables\.{new}"):
            __import__(f"sim.drivers.{old}")
