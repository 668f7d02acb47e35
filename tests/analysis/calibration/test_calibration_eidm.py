"""EIDM calibration through real SUMO: a known driver recovered from pairs SUMO's EIDM generated,
the SUMO scoring equal to the replica's for IDM, and the CLI wiring of ``--cf-model-name eidm``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from shared_data import PAIRS_DIR

from analysis.calibration import CarFollowingPair, PairBatch, evaluate, fit_population, load_pairs, load_result
from analysis.calibration.models import CFParams
from analysis.calibration.objective import spacing_rmse
from analysis.calibration.sumo_fit import SumoRmse, fit_population_sumo
from scenarios.errors import SpecError

#: the driver to recover (accel, tau, minGap fitted; decel and desired speed given)
TRUE = CFParams(accel=1.4, decel=2.5, tau=1.6, minGap=3.5, maxSpeed=20.0)
FITTED3 = ("accel", "tau", "minGap")


def _leader_profiles() -> list[np.ndarray]:
    """Three 60 s congested leader speed profiles (m/s): slow waves, a full stop, faster waves."""
    t = np.arange(600) * 0.1
    stop = np.clip(np.where(t < 20, 10 - 0.8 * t, np.where(t < 30, 0.0, 1.2 * (t - 30))), 0, 12)
    return [8 + 5 * np.sin(2 * np.pi * t / 25), stop, 12 + 3 * np.sin(2 * np.pi * t / 12 + 1.0)]


def _generate_pairs(params: CFParams) -> list[CarFollowingPair]:
    """Pairs whose follower is SUMO's EIDM (noise off) with ``params``, run in a fresh process."""
    profiles = [v.tolist() for v in _leader_profiles()]
    code = textwrap.dedent(f"""
        import json, numpy as np
        from analysis.calibration.models import CFParams
        from analysis.calibration.sumo_replay import ReplayCase, run_sumo_pairs
        cases = [ReplayCase(v_leader=np.array(v), x_leader0=100.0, x_follower0=100.0 - 4.5 - g, v_follower0=vf)
                 for v, g, vf in zip({profiles!r}, [15.0, 25.0, 20.0], [7.0, 10.0, 12.0])]
        r = run_sumo_pairs(cases, CFParams(**{params.as_dict()!r}), model="eidm")
        print(json.dumps({{k: getattr(r, k).tolist() for k in ("x_leader", "v_leader", "x_follower", "v_follower")}}))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    r = {k: np.array(a) for k, a in json.loads(out.stdout.splitlines()[-1]).items()}
    n = r["x_leader"].shape[1]
    return [CarFollowingPair(name=f"synthetic{i}", group=f"s/{i}", t=np.arange(n) * 0.1,
                             x_follower=r["x_follower"][i], v_follower=r["v_follower"][i],
                             x_leader=r["x_leader"][i], v_leader=r["v_leader"][i], leader_length=4.5)
            for i in range(len(r["x_leader"]))]


@pytest.fixture(scope="module")
def synthetic() -> list[CarFollowingPair]:
    return _generate_pairs(TRUE)


@pytest.mark.sumo
def test_eidm_replay_is_deterministic_and_defaults_differ(synthetic) -> None:
    """The true driver replayed through the evaluation scores zero (noise off, same run twice);
    SUMO's EIDM defaults follow the same leaders with metres of error."""
    ev = evaluate(TRUE, synthetic, model="eidm", workers=1)
    assert ev.model == "eidm" and len(ev.pairs) == 3
    assert max(p.rmse_m for p in ev.pairs) < 1e-6
    assert min(p.default_rmse_m for p in ev.pairs) > 0.5 and ev.win_fraction == 1.0


@pytest.mark.sumo
def test_eidm_fit_recovers_known_driver(synthetic) -> None:
    """Nelder-Mead through SUMO, started from SUMO's defaults, finds the generating driver."""
    base = CFParams(decel=TRUE.decel, maxSpeed=TRUE.maxSpeed)
    pop, med, runs = fit_population_sumo(synthetic, model="eidm", fitted=FITTED3, base=base,
                                         starts=(base,), max_evals=80, objective="rmse", workers=1)
    assert runs <= 80
    assert med < 0.1  # defaults: metres (test above)
    assert pop.tau == pytest.approx(TRUE.tau, abs=0.05)  # measured: 1.598, 3.489, 1.398 (start 1.0, 2.5, 2.6)
    assert pop.minGap == pytest.approx(TRUE.minGap, abs=0.15)
    assert pop.accel == pytest.approx(TRUE.accel, abs=0.1)


@pytest.mark.sumo
def test_sumo_scoring_equals_replica_for_idm() -> None:
    """SumoRmse (SUMO's gap over steps 1 .. len-1) scores real pairs as the replica does (IDM)."""
    pairs = load_pairs(PAIRS_DIR)[::4]
    params = [CFParams(), CFParams(accel=1.2, decel=2.0, tau=1.5, minGap=2.0, maxSpeed=25.0)]
    with SumoRmse(pairs, "idm", workers=2) as sim:
        r = sim(params)
        assert sim.runs == 2
    batch = PairBatch.from_pairs(pairs)
    for c, p in enumerate(params):
        replica = batch.unsort(spacing_rmse("idm", batch, p.as_dict()))
        np.testing.assert_allclose(r[:, c], replica, atol=0.02)
    assert r.max() > 1.0


def test_bad_model_names_are_rejected() -> None:
    pairs = load_pairs(PAIRS_DIR, limit=2)
    with pytest.raises(SpecError, match="no numpy replica"):
        fit_population(pairs, model="eidm")
    with pytest.raises(SpecError, match="'eidm'"):
        evaluate(CFParams(), pairs, model="eidmx")
    with pytest.raises(SpecError, match="'eidm'"):
        SumoRmse(pairs, "wiedemann")
    with pytest.raises(SpecError, match="max_evals"):
        fit_population_sumo(pairs, max_evals=3)


def test_unguarded_script_fails_with_a_hint_instead_of_hanging(tmp_path: Path) -> None:
    """A script that calls the SUMO scoring at module level (no ``__main__`` guard): each spawned
    worker re-imports it; the worker refuses to start a pool of its own, and the parent reports
    the dead worker. The pairs (~0.5 MB pickled) exceed a pipe's buffer, which used to block the
    parent forever writing them to a worker that had died before reading them."""
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent("""
        import numpy as np
        from analysis.calibration import CarFollowingPair
        from analysis.calibration.models import CFParams
        from analysis.calibration.sumo_fit import SumoRmse
        t = np.arange(20000) * 0.1
        pair = CarFollowingPair(name="p", group="g", t=t, x_follower=10 * t, v_follower=10 + 0 * t,
                                x_leader=10 * t + 30, v_leader=10 + 0 * t, leader_length=4.5)
        with SumoRmse([pair], "idm", workers=1) as sim:
            sim([CFParams()])
    """))
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240, cwd=tmp_path,
                         env={**os.environ, "TMPDIR": str(tmp)})
    assert out.returncode == 1
    assert "worker process imported the main script" in out.stderr  # the worker's own error
    assert "a SUMO worker process died" in out.stderr  # the parent's
    assert not list(tmp.iterdir())  # the pairs file removed


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.sumo
def test_cli_fit_and_evaluate_eidm(tmp_path: Path) -> None:
    out = tmp_path / "eidm.toml"
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(out), "--cf-model-name", "eidm",
             "--limit", "4", "--max-evals", "10", "--workers", "1")
    assert r.returncode == 0, r.stderr
    assert "no per-pair fits" in r.stderr
    res = load_result(out)
    assert res.model == "eidm" and res.n_pairs == 4 and res.per_pair == ()
    assert res.population != CFParams()  # moved away from the start
    # fitted on the first 4 files without a split: an evaluation that holds followers out must be
    # the fit's own split, so this one scores every pair and counts the fit's own
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR), "--holdout", "0.3",
             "--json", "--workers", "1")
    assert r.returncode == 2 and "have a follower" in r.stderr, r.stderr
    r = _cli("calibrate", "evaluate", "--params", str(out), "--pairs", str(PAIRS_DIR), "--json", "--workers", "1")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["model"] == "eidm" and d["n_pairs"] > 5 and d["n_pairs_in_fit"] >= 4
    assert 0 < d["median_rmse_m"] < 20 and 0 < d["default_median_rmse_m"] < 20
    assert d["median_rmse_m"] != d["default_median_rmse_m"]
    iv = d["intervals"]["median_ratio"]
    assert iv["low"] <= iv["value"] <= iv["high"]


def test_cli_rejects_bad_model_and_budget(tmp_path: Path) -> None:
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(tmp_path / "x.toml"), "--cf-model-name", "eidn")
    assert r.returncode == 2 and "invalid choice: 'eidn'" in r.stderr
    r = _cli("calibrate", "fit", "--pairs", str(PAIRS_DIR), "--out", str(tmp_path / "x.toml"), "--cf-model-name", "eidm",
             "--max-evals", "0")
    assert r.returncode == 2 and "--max-evals" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    bad = tmp_path / "p.toml"
    bad.write_text('model = "eidm2"\n[population]\naccel = 1.0\n')
    r = _cli("calibrate", "evaluate", "--params", str(bad), "--pairs", str(PAIRS_DIR))
    assert r.returncode == 2 and "eidm2" in r.stderr and "'eidm'" in r.stderr
    assert not (tmp_path / "x.toml").exists()


def test_eidm_vtypes_carry_the_fitted_attributes() -> None:
    """An EIDM population becomes EIDM vTypes with delta and the noise off, as fitted."""
    from analysis.calibration import CalibrationResult, driver_members
    from analysis.calibration.vtypes import to_vtype_specs
    from scenarios.spec.model import VTypeSpec

    res = CalibrationResult(model="eidm", fitted=FITTED3, population=TRUE, population_median_rmse_m=1.0,
                            per_pair=(), spread=(), n_pairs=3, seconds_population=1.0, seconds_per_pair=0.0)
    template = VTypeSpec(id="car", car_follow_model="IDM", cf_params=(("delta", 3.0), ("sigmagap", 0.1)))
    (spec,) = to_vtype_specs(driver_members(res, 1), template, "eidm")
    cf = dict(spec.cf_params)
    assert spec.car_follow_model == "EIDM" and spec.tau == TRUE.tau and spec.sigma == 0.0
    assert cf == {"delta": 4.0, "sigmaleader": 0.0, "sigmagap": 0.0, "sigmaerror": 0.0}
