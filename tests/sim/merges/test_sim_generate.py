"""``merge-irl generate / encounters / demo`` end to end, and aborted runs leave no complete-looking output."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from sim_testutil import default_sigint

from irl.domains.merge.bins import MergeBins
from irl.domains.merge.encounters import ENCOUNTER_COLUMNS
from irl.domains.merge.states import state_parts
from irl.result import SavedModel
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.merges.encounters import MERGE_COLUMNS
from sim.merges.generate import OUTPUT_FILES
from sim.runtime.outputs import write_parquet
from sim.runtime.schema import COLUMNS

pytestmark = pytest.mark.sumo


def cli(args, cache, **kw):
    env = dict(os.environ, MERGE_IRL_CACHE=str(cache))
    return subprocess.run([sys.executable, "-m", "analysis", *args], capture_output=True, text=True, env=env, **kw)


def test_generate_writes_outputs_and_spec(tmp_path):
    out = tmp_path / "run"
    # merge-frame: the one rule `merge-irl encounters` can apply to a saved table (the default
    # in-lane rule needs the observing controller during the run: tests/test_take_over.py)
    r = cli(["generate", "--scenario", "synthetic", "--duration", "100", "--seed", "3", "--no-progress",
             "--encounter-rule", "merge-frame", "--out", str(out)], tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    t = pd.read_parquet(out / "trajectories.parquet")
    assert list(t.columns) == list(COLUMNS) and len(t) > 0
    assert list(pd.read_parquet(out / "encounters.parquet").columns) == list(ENCOUNTER_COLUMNS)
    assert list(pd.read_parquet(out / "merges.parquet").columns) == list(MERGE_COLUMNS)
    used = load_scenario(out / "scenario.toml")
    assert used == with_overrides(load_scenario("synthetic"), seed=3, duration_s=100.0)
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
    # encounters from the saved table = the ones generate wrote
    r2 = cli(["encounters", str(out / "trajectories.parquet"), "--out", str(tmp_path / "e.parquet")], tmp_path / "cache")
    assert r2.returncode == 0, r2.stderr
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "e.parquet"), pd.read_parquet(out / "encounters.parquet"))
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "e.merges.parquet"), pd.read_parquet(out / "merges.parquet"))


def test_learn_merge_accepts_what_generate_writes_with_frames_without_car_c(tmp_path):
    out = tmp_path / "run"
    r = cli(["generate", "--scenario", "synthetic", "--duration", "100", "--seed", "3", "--no-progress",
             "--out", str(out)], tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    enc_path = out / "encounters.parquet"
    enc = pd.read_parquet(enc_path)
    if not enc.d_AC.isna().any():
        # no frame without C in this short run: take a C off the road for part of its encounter
        # (drop its trajectory rows) and extract the encounters again, as a user would
        t = pd.read_parquet(out / "trajectories.parquet")
        sizes = enc[enc.C_id != 0].groupby("encounter_id").size()  # the longest window: frames to drop
        row = enc[enc.encounter_id == sizes.idxmax()].iloc[0]
        drop = (t.Vehicle_ID == row.C_id) & (t.Frame_ID <= row.merge_frame - 3)
        assert drop.any()
        t[~drop].to_parquet(tmp_path / "t.parquet")
        enc_path = tmp_path / "e.parquet"
        r = cli(["encounters", str(tmp_path / "t.parquet"), "--out", str(enc_path)], tmp_path / "cache")
        assert r.returncode == 0, r.stderr
        enc = pd.read_parquet(enc_path)
    no_c = enc.d_AC.isna()
    assert no_c.any() and (no_c == enc.v_AC.isna()).all() and (~no_c).any()
    model = tmp_path / "m.json"
    r = cli(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(enc_path), "--settings", "reference",
             "--out", str(model), "--no-progress"], tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    m = SavedModel.load(model)
    # encounter tables default to the driver encoding: the paper's 1250 states x A's previous action
    assert m.domain == "merge" and m.state_encoding == "driver" and m.q.shape == (6250, 5)
    assert np.all(np.isfinite(m.theta))
    # the no-C frames were encoded by the no-lead-car rule (farthest d_AC bin), not rejected
    bins = MergeBins.from_dict({k: list(v) for k, v in m.bin_edges.items()})
    parts = state_parts(bins.encode(enc[no_c]))
    assert (parts[:, 1] == 0).all() and (parts[:, 3] == bins.no_lead_v_AC_bin()).all()


def test_generate_bad_spec_fails_before_sumo_naming_the_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[road]\nramp_length_m = -5\n')
    r = cli(["generate", "--scenario", str(bad), "--out", str(tmp_path / "o")], tmp_path / "cache")
    assert r.returncode == 2
    assert "bad.toml: road.ramp_length_m: must be positive, got -5" in r.stderr
    assert not (tmp_path / "o").exists() and not (tmp_path / "cache").exists()


def test_basic_demo_summary(tmp_path):
    from analysis.demo.basic import run_basic_demo

    summary = run_basic_demo(tmp_path / "demo", scenario="synthetic", seed=1, duration_s=120, progress=False)
    text = summary.format()
    assert "vehicles:" in text and "merges (lane 7 -> 6):" in text and "lane 6:" in text


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
def test_interrupted_generate_leaves_no_complete_looking_output(tmp_path, sig):
    out = tmp_path / "run"
    out.mkdir()
    for name in OUTPUT_FILES:  # a previous run's files must not survive as if they were this run's
        (out / name).write_text("stale")
    env = dict(os.environ, MERGE_IRL_CACHE=str(tmp_path / "cache"))
    proc = subprocess.Popen([sys.executable, "-m", "analysis", "generate", "--scenario", "i80", "--duration",
                             "3000", "--no-progress", "--out", str(out)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    deadline = time.time() + 60
    while (out / "trajectories.parquet").exists() and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)  # well inside the simulation (3000 s of i80 take much longer)
    assert proc.poll() is None, "the run finished before it could be interrupted"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    if sig == signal.SIGINT:
        assert proc.returncode == 130 and "interrupted" in err
    else:
        assert proc.returncode == -signal.SIGKILL
    assert [p.name for p in out.iterdir() if not p.name.startswith(".")] == []


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    class Boom(pd.DataFrame):
        def to_parquet(self, path, **kw):
            open(path, "wb").write(b"PAR1 half")
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_parquet(Boom({"a": [1]}), tmp_path / "t.parquet")
    assert list(tmp_path.iterdir()) == []
