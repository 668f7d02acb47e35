"""The numpy car-following replica equals real SUMO (libsumo) step for step."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from shared_data import PAIRS_DIR

from analysis.calibration import PairBatch, load_pairs
from analysis.calibration.models import CFParams, simulate_follower
from analysis.calibration.objective import spacing_rmse

PARAMS = [
    CFParams(),
    CFParams(accel=1.2, decel=2.0, tau=1.5, minGap=2.0, maxSpeed=25.0),
    CFParams(accel=0.8, decel=1.5, tau=0.8, minGap=3.0, maxSpeed=33.0, delta=3.0),
    CFParams(tau=2.0, emergencyDecel=6.0),
]
# initial gap (m) and follower speed (m/s): comfortable, close, very close (emergency), far
STARTS = [(30.0, 15.0), (10.0, 16.0), (5.0, 14.0), (60.0, 20.0)]


def _leader_profile() -> np.ndarray:
    """Cruise, brake hard (6 m/s^2) to a stop, stand, accelerate, then a noisy stretch."""
    t = np.arange(700) * 0.1
    v = np.where(t < 10, 15.0, np.maximum(15 - 6 * (t - 10), 0.0))
    v = np.where(t > 17.5, np.minimum(2.0 * (t - 17.5), 20.0), v)
    rng = np.random.default_rng(1)
    noise = np.clip(np.cumsum(rng.normal(0, 0.3, len(t))), -3, 3) * 0.1
    return np.where(t > 40, np.clip(v + np.cumsum(noise) * 0.5, 0, 30), v)


def _run_sumo(model: str, action_step_s: float = 0.1) -> dict:
    v = _leader_profile().tolist()
    code = textwrap.dedent(f"""
        import json, numpy as np
        from analysis.calibration.models import CFParams
        from analysis.calibration.sumo_replay import ReplayCase, run_sumo_pairs
        params = [CFParams(**d) for d in {json.dumps([p.as_dict() for p in PARAMS])}]
        v = np.array({json.dumps(v)})
        cases = [ReplayCase(v_leader=v, x_leader0=100.0, x_follower0=100.0 - 4.5 - g, v_follower0=vf)
                 for g, vf in {STARTS!r}]
        r = run_sumo_pairs(cases, params, model={model!r}, action_step_s={action_step_s!r})
        print(json.dumps({{k: getattr(r, k).tolist() for k in ("x_leader", "v_leader", "x_follower", "v_follower")}}))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    return {k: np.array(a) for k, a in json.loads(out.stdout.splitlines()[-1]).items()}


@pytest.mark.sumo
@pytest.mark.parametrize("model", ["idm", "krauss"])
def test_replica_matches_sumo(model: str) -> None:
    r = _run_sumo(model)
    np.testing.assert_allclose(r["v_leader"][0], _leader_profile(), atol=1e-4)  # leader replayed
    for i, p in enumerate(PARAMS):
        x, v = simulate_follower(model, r["x_leader"][i], r["v_leader"][i], 4.5,
                                 r["x_follower"][i][0], r["v_follower"][i][0], p.as_dict())
        np.testing.assert_allclose(v, r["v_follower"][i], atol=1e-9, rtol=0)
        np.testing.assert_allclose(x, r["x_follower"][i], atol=1e-8, rtol=0)
    gaps = r["x_leader"] - 4.5 - r["x_follower"]
    assert (r["v_follower"].min(axis=1) < 0.05).any()  # the check covers stops ...
    assert gaps.min() < 3.0  # ... and close following


@pytest.mark.sumo
@pytest.mark.parametrize("model", ["idm", "krauss"])
@pytest.mark.parametrize("action_steps", [2, 5, 10, 15])
def test_replica_matches_sumo_with_action_step(model: str, action_steps: int) -> None:
    """vType ``actionStepLength`` = action_steps x 0.1 s (decisions only every that long, the
    acceleration held in between) in SUMO equals ``simulate_follower(..., action_steps=)``."""
    r = _run_sumo(model, round(action_steps * 0.1, 1))
    for i, p in enumerate(PARAMS):
        x, v = simulate_follower(model, r["x_leader"][i], r["v_leader"][i], 4.5,
                                 r["x_follower"][i][0], r["v_follower"][i][0], p.as_dict(), action_steps=action_steps)
        np.testing.assert_allclose(v, r["v_follower"][i], atol=1e-9, rtol=0)
        np.testing.assert_allclose(x, r["x_follower"][i], atol=1e-8, rtol=0)
        x1, _ = simulate_follower(model, r["x_leader"][i], r["v_leader"][i], 4.5,
                                  r["x_follower"][i][0], r["v_follower"][i][0], p.as_dict())
        assert np.abs(x1 - x).max() > 0.05  # the action step changes the trajectory: the check has teeth


def test_action_steps_must_be_positive_whole() -> None:
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="action_steps"):
            simulate_follower("idm", np.zeros(3), np.zeros(3), 4.5, -10.0, 0.0, CFParams().as_dict(), action_steps=bad)


def test_replica_broadcasts_candidates() -> None:
    """(P, 1) pairs x (C,) parameter sets equals simulating each set alone."""
    v_l = _leader_profile()[:200]
    x_l = 100 + np.cumsum(v_l) * 0.1
    xl = np.stack([x_l, x_l + 5])[:, None, :]
    vl = np.stack([v_l, v_l])[:, None, :]
    tau = np.array([0.8, 1.0, 1.6])
    params = {**CFParams().as_dict(), "tau": tau}
    x, v = simulate_follower("idm", xl, vl, np.array([[4.5], [4.5]]), np.array([[70.0], [72.0]]),
                             np.array([[12.0], [12.0]]), params)
    assert x.shape == (2, 3, 200)
    for i in range(2):
        for c in range(3):
            xs, _ = simulate_follower("idm", xl[i, 0], vl[i, 0], 4.5, [70.0, 72.0][i], 12.0,
                                      {**CFParams().as_dict(), "tau": tau[c]})
            np.testing.assert_array_equal(x[i, c], xs)


def _run_sumo_on_real_pairs(model: str, params: CFParams, names: list[str]) -> dict:
    """Real pairs in real SUMO: the recorded leader speeds replayed, the follower started from
    its recorded gap and speed; SUMO's leader and follower positions (m, shifted) per step."""
    code = textwrap.dedent(f"""
        import json, numpy as np
        from analysis.calibration import load_pairs
        from analysis.calibration.models import CFParams
        from analysis.calibration.sumo_replay import ReplayCase, run_sumo_pairs
        pairs = {{p.name: p for p in load_pairs({str(PAIRS_DIR)!r})}}
        sel = [pairs[n] for n in {names!r}]
        cases = [ReplayCase(v_leader=p.v_leader, x_leader0=100.0,
                            x_follower0=100.0 - (p.x_leader[0] - p.x_follower[0]),
                            v_follower0=float(p.v_follower[0]), leader_length=p.leader_length) for p in sel]
        r = run_sumo_pairs(cases, CFParams(**{params.as_dict()!r}), model={model!r})
        print(json.dumps({{"x_leader": r.x_leader.tolist(), "x_follower": r.x_follower.tolist()}}))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    return {k: np.array(a) for k, a in json.loads(out.stdout.splitlines()[-1]).items()}


@pytest.mark.sumo
@pytest.mark.parametrize("model", ["idm", "krauss"])
@pytest.mark.parametrize("params", [CFParams(), CFParams(accel=1.6, decel=1.5, tau=1.3, minGap=2.5, maxSpeed=23.0)],
                         ids=["defaults", "calibrated"])
def test_replica_rmse_equals_sumo_on_real_pairs(model: str, params: CFParams) -> None:
    """What the fit minimises is what SUMO does: on real NGSIM pairs, the spacing RMSE the
    replica computes from the recorded leader positions equals the RMSE of real SUMO replaying
    the recorded leader speeds (the two leader paths differ by the data's few centimetres of
    position/speed inconsistency, hence the 2 cm tolerance)."""
    pairs = load_pairs(PAIRS_DIR)[::6]
    r = _run_sumo_on_real_pairs(model, params, [p.name for p in pairs])
    batch = PairBatch.from_pairs(pairs)
    replica = batch.unsort(spacing_rmse(model, batch, params.as_dict()))
    for i, p in enumerate(pairs):
        n = len(p)
        sumo_gap = r["x_leader"][i, :n] - p.leader_length - r["x_follower"][i, :n]
        sumo_rmse = np.sqrt(np.mean((sumo_gap[1:] - p.spacing[1:]) ** 2))
        assert sumo_rmse == pytest.approx(replica[i], abs=0.02), p.name
    assert replica.max() > 1.0  # the pairs are not trivially followed: the check has teeth
