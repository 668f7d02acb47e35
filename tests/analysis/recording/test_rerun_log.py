"""The .rrd written by the closed loop, read back with rerun.chunk.RrdReader."""

from __future__ import annotations

import re

import numpy as np
import pytest
import rerun as rr

from analysis.evaluation.episode import run_episode
from analysis.recording.files import close_recording, open_recording, recording_identity
from analysis.recording.log import log_training
from analysis.recording.read import read_blueprint, read_entities, read_rrd_table, recording_info
from analysis.recording.scene import ROLE_IDS, ROLE_LABELS
from irl.domains.merge.bins import MergeBins
from scenarios.loader import load_scenario
from sim.drivers.learned import LearnedPolicy

EDGES = {"d_AC": (35, 60, 90, 130), "d_AB": (10, 30, 60, 100), "v_AC": (-7.5, -2.5, 2.5, 7.5),
         "v_AB": (-7.5, -2.5, 2.5, 7.5)}


def _col(batches, name):
    return [b.column(name) for b in batches]


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    path = tmp_path_factory.mktemp("rrd") / "run.rrd"
    rng = np.random.default_rng(7)
    q = rng.normal(size=(1250, 5))
    policy = LearnedPolicy(q - np.log(np.exp(q).sum(axis=1, keepdims=True)), MergeBins.from_dict(EDGES), name="random-q")
    res = run_episode(load_scenario("synthetic"), policy, 3, duration_s=120.0, rrd_path=path, keep_table=True)
    return path, res


@pytest.mark.sumo
def test_rrd_has_expected_entities(logged):
    path, res = logged
    assert path.exists() and not path.with_name(path.name + ".partial").exists()
    ents = read_entities(path)
    assert "/world/lanes" in ents and "/world/vehicles" in ents and "/world" in ents
    a_ids = sorted(res.controls.a_id.unique())
    assert a_ids
    for a in a_ids:
        for suffix in ("policy/A_{a}/probs", "policy/A_{a}/action", "policy/A_{a}/features/safe",
                       "metrics/A_{a}/speed", "metrics/A_{a}/d_AC", "metrics/A_{a}/d_AB"):
            assert "/" + suffix.format(a=a) in ents, suffix.format(a=a)
    lanes = ents["/world/lanes"][0]
    assert lanes.schema.metadata is not None
    # static lanes: no timeline column
    assert "step" not in lanes.schema.names
    strips = lanes.column("LineStrips2D:strips")[0].as_py()
    assert len(strips) == 4  # synthetic: 3 main lanes + lane 7


@pytest.mark.sumo
def test_vehicle_positions_and_roles_match_the_table(logged):
    path, res = logged
    table = res.table
    batches = read_entities(path)["/world/vehicles"]
    steps = np.concatenate([b.column("step").to_numpy() for b in batches])
    frames = np.sort(table.Frame_ID.unique())
    assert np.array_equal(np.sort(steps), frames)  # one row per recorded frame
    # flatten: step, vehicle id, centre, half size, class id
    rows = []
    for b in batches:
        st = b.column("step").to_numpy()
        ids = b.column("vehicle_id").to_pylist()
        cen = b.column("Boxes2D:centers").to_pylist()
        half = b.column("Boxes2D:half_sizes").to_pylist()
        cls = b.column("Boxes2D:class_ids").to_pylist()
        lab = b.column("Boxes2D:labels").to_pylist()
        for i, s in enumerate(st):
            for v, c, h, k, lb in zip(ids[i], cen[i], half[i], cls[i], lab[i]):
                rows.append((int(s), int(v), c[0] + h[0], c[1], 2 * h[0], 2 * h[1], k, lb))
    import pandas as pd

    rr_df = pd.DataFrame(rows, columns=["Frame_ID", "Vehicle_ID", "front_x", "y", "len", "wid", "role", "label"])
    assert len(rr_df) == len(table)  # every vehicle of every frame, in one entity
    m = table.merge(rr_df, on=["Frame_ID", "Vehicle_ID"])
    assert len(m) == len(table)
    # float32 in the file: within 0.01 ft
    np.testing.assert_allclose(m.front_x, m.Global_X, atol=0.01)
    np.testing.assert_allclose(m.y, m.Global_Y, atol=0.01)
    # boxes in the vehicles' real size; labels on A, B, C only
    np.testing.assert_allclose(m.len, m.v_Length, atol=0.01)
    np.testing.assert_allclose(m.wid, m.v_Width, atol=0.01)
    assert (m.label[m.role == ROLE_IDS["other"]] == "").all()
    tagged = m[m.role != ROLE_IDS["other"]]
    assert len(tagged) and all(lb.split() == [r, str(v)] for lb, r, v in
                               zip(tagged.label, tagged.role.map(dict(enumerate(ROLE_LABELS))), tagged.Vehicle_ID))
    # the controlled cars are role A exactly in their control windows (decisions frames)
    dec = res.decisions
    ctl_rows = m.merge(dec[["frame", "a_id"]], left_on=["Frame_ID", "Vehicle_ID"], right_on=["frame", "a_id"])
    assert len(ctl_rows) == len(dec)
    assert (ctl_rows.role == ROLE_IDS["A"]).all()
    b_rows = m.merge(dec[["frame", "b_id"]], left_on=["Frame_ID", "Vehicle_ID"], right_on=["frame", "b_id"])
    assert (b_rows.role == ROLE_IDS["B"]).all()


@pytest.mark.sumo
def test_policy_values_match_decisions(logged):
    path, res = logged
    ents = read_entities(path)
    dec = res.decisions
    a = int(dec.a_id.iloc[0])
    d = dec[dec.a_id == a]
    act = ents[f"/policy/A_{a}/action"]
    steps = np.concatenate([b.column("step").to_numpy() for b in act])
    vals = np.concatenate([np.concatenate(b.column("Scalars:scalars").to_pylist()) for b in act])
    np.testing.assert_array_equal(steps, d.frame.to_numpy())
    np.testing.assert_array_equal(vals, d.action.to_numpy(float))
    probs = [b for b in ents[f"/policy/A_{a}/probs"] if "step" in b.schema.names]
    got = np.array([row for b in probs for row in b.column("Scalars:scalars").to_pylist()])
    np.testing.assert_allclose(got, d[["p0", "p1", "p2", "p3", "p4"]].to_numpy(), rtol=0, atol=1e-12)
    assert np.ptp(got[:, 0]) > 0  # the probabilities vary with the state
    states = MergeBins.from_dict(EDGES).states(d.d_AC, d.d_AB, d.v_AC, d.v_AB, d.b_is_truck.to_numpy(bool))
    np.testing.assert_array_equal(states, d.state.to_numpy())
    speed = ents[f"/metrics/A_{a}/speed"]
    sp_steps = np.concatenate([b.column("step").to_numpy() for b in speed])
    sp_vals = np.concatenate([np.concatenate(b.column("Scalars:scalars").to_pylist()) for b in speed])
    assert set(d.frame) <= set(sp_steps)
    # A's logged speed is the table's v_Vel of A at every logged step
    rows = res.table[res.table.Vehicle_ID == a].set_index("Frame_ID").v_Vel
    np.testing.assert_allclose(sp_vals, rows.loc[sp_steps].to_numpy(), rtol=0, atol=1e-9)
    for name in ("d_AC", "d_AB", "ttc"):
        series = ents.get(f"/metrics/A_{a}/{name}", [])
        vals = np.concatenate([np.concatenate(b.column("Scalars:scalars").to_pylist()) for b in series] or [[]])
        assert np.all(np.isfinite(vals)), name
        if name == "ttc":
            assert np.all(vals >= 0) and len(vals) <= len(sp_vals)


def test_training_traces_are_logged(tmp_path):
    path = tmp_path / "train.rrd"
    rec, tmp = open_recording(path, recording_id="t")
    ll = np.array([-50.0, -40.0, -35.5])
    th = np.array([[0.1, 0.2, 0.3], [0.2, 0.3, 0.4], [0.3, 0.5, 0.1]])
    log_training(rec, "qavg", ll, th, ("safe", "time_to_travel", "ahead_of_truck"))
    close_recording(rec, tmp, path)
    ents = read_entities(path)
    b = ents["/train/qavg/loglik"]
    vals = np.concatenate([np.concatenate(x.column("Scalars:scalars").to_pylist()) for x in b])
    np.testing.assert_array_equal(vals, ll)
    its = np.concatenate([x.column("iteration").to_numpy() for x in b])
    np.testing.assert_array_equal(its, [0, 1, 2])
    t = ents["/train/qavg/theta/time_to_travel"]
    np.testing.assert_array_equal(np.concatenate([np.concatenate(x.column("Scalars:scalars").to_pylist()) for x in t]), th[:, 1])


@pytest.mark.sumo
def test_recording_is_named_for_its_scenario_policy_and_seed(logged):
    path, _ = logged
    info = recording_info(path)
    assert info["application_id"] == "merge-irl"
    assert re.fullmatch(r"merge-irl/synthetic/random-q/seed3/run-[0-9a-f]{10}", info["recording_id"])
    assert info["name"] == f"random-q on synthetic, seed 3 (run {info['recording_id'][-10:]})"


@pytest.mark.sumo
def test_recording_ids_are_unique_per_run_and_deterministic(tmp_path):
    """The SUMO baseline of two runs, and two different models of one name and
    seed, got one id, so the viewer merged or dropped them; the same run repeated keeps its id."""
    from sim.drivers.policy import SumoPolicy

    def rid(folder, policy):
        path = tmp_path / folder / "rerun" / f"{policy.name}.rrd"
        run_episode(load_scenario("synthetic"), policy, 3, duration_s=70.0, rrd_path=path)
        return recording_info(path)["recording_id"]

    sumo_a, sumo_b, sumo_a_again = rid("a", SumoPolicy()), rid("b", SumoPolicy()), rid("a", SumoPolicy())
    assert sumo_a != sumo_b and sumo_a == sumo_a_again
    rng = np.random.default_rng(0)
    bins = MergeBins.from_dict(EDGES)
    one, two = (LearnedPolicy(np.log(np.full((1250, 5), 0.2)), bins, name="model"),
                LearnedPolicy(np.log(rng.dirichlet(np.ones(5), size=1250)), bins, name="model"))
    ids = {rid("m", one), rid("m", two), rid("a", one)}  # the same file name, policy name and seed
    assert len(ids) == 3 and sumo_a not in ids


def test_recording_ids_differ_by_policy_seed_and_episode():
    ids = {recording_identity(s, p, seed, ep)[0] for s in ("synthetic", "i80") for p in ("qavg", "sumo")
           for seed in (1, 2) for ep in (None, 0, 1)}
    assert len(ids) == 2 * 2 * 2 * 3
    assert recording_identity("i80", "qavg", 4, 2) == ("merge-irl/i80/qavg/seed4/episode2", "qavg on i80, seed 4, episode 2")
    assert recording_identity("i80", "qavg", 4, 2, run="0123456789") == (
        "merge-irl/i80/qavg/seed4/episode2/run-0123456789", "qavg on i80, seed 4, episode 2 (run 0123456789)")


@pytest.mark.sumo
def test_rrd_table_holds_what_the_episode_logged(logged):
    path, res = logged
    table = read_rrd_table(path)
    assert not table.entity.eq("/__properties").any()
    assert read_rrd_table(path, properties=True).entity.eq("/__properties").any()
    # one vehicles row per recorded frame, its boxes the frame's vehicles
    veh = table[table.entity == "/world/vehicles"].sort_values("step")
    frames = res.table.groupby("Frame_ID").size()
    np.testing.assert_array_equal(veh.step.to_numpy(), frames.index.to_numpy())
    np.testing.assert_array_equal([len(v) for v in veh["vehicle_id"]], frames.to_numpy())
    a = int(res.decisions.a_id.iloc[0])
    d = res.decisions[res.decisions.a_id == a]
    speed = read_rrd_table(path, f"/metrics/A_{a}/speed")
    assert set(speed.entity) == {f"/metrics/A_{a}/speed"}
    v = res.table[res.table.Vehicle_ID == a].set_index("Frame_ID").v_Vel
    np.testing.assert_allclose(speed["Scalars:scalars"].to_numpy(float), v.loc[speed.step].to_numpy(), rtol=0, atol=1e-9)
    # sim_time in seconds: frames are 0.1 s apart
    np.testing.assert_allclose(np.diff(speed.sim_time.to_numpy(float)), 0.1 * np.diff(speed.step.to_numpy()), atol=1e-9)
    probs = table[(table.entity == f"/policy/A_{a}/probs") & ~table.static]
    np.testing.assert_allclose(np.stack(probs["Scalars:scalars"].to_numpy()),
                               d[["p0", "p1", "p2", "p3", "p4"]].to_numpy(), rtol=0, atol=1e-12)


def test_rrd_table_of_training_traces(tmp_path):
    path = tmp_path / "train.rrd"
    rec, tmp = open_recording(path, recording_id="train-test", name="a name")
    ll = np.array([-50.0, -40.0, -35.5])
    log_training(rec, "mlirl", ll, np.ones((3, 2)))
    close_recording(rec, tmp, path)
    t = read_rrd_table(path, "/train/mlirl/loglik")
    np.testing.assert_array_equal(t["iteration"].to_numpy(), [0, 1, 2])
    np.testing.assert_array_equal(t["Scalars:scalars"].to_numpy(float), ll)
    assert recording_info(path)["name"] == "a name" and recording_info(path)["recording_id"] == "train-test"
    assert read_rrd_table(path, "/nothing").empty
    with pytest.raises(FileNotFoundError, match="missing.rrd"):
        read_rrd_table(tmp_path / "missing.rrd")


@pytest.mark.sumo
def test_blueprint_is_shipped_with_the_recording(logged):
    path, res = logged
    views = {v["name"]: v for v in read_blueprint(path)}
    a_ids = list(dict.fromkeys(int(a) for a in res.controls.sort_values(["start_frame", "a_id"]).a_id))
    merge, section = views["merge (follows car A)"], views["section"]
    assert merge["kind"] == section["kind"] == "2D"
    assert merge["origin"] == "/follow" and merge["contents"] == ["/world/**"] and section["origin"] == "/"
    series = {n: v for n, v in views.items() if v["kind"] == "TimeSeries"}
    for q in ("speed", "d_AB", "d_AC", "ttc"):
        (v,) = [v for v in series.values() if v["contents"] and v["contents"][0].endswith("/" + q)]
        if q == "ttc":  # only the cars that closed in on their leader have a TTC series
            assert v["contents"] and set(v["contents"]) <= {f"/metrics/A_{a}/ttc" for a in a_ids}
        else:
            assert v["contents"] == [f"/metrics/A_{a}/{q}" for a in a_ids]
    assert any(v["contents"] == [f"/policy/A_{a}/action" for a in a_ids] for v in series.values())
    bars = views["action probabilities now"]
    assert bars["kind"] == "2D" and bars["origin"] == "/policy/action_bars"
    assert not any(n.startswith(("log-likelihood", "weights")) for n in views)  # no training logged here
    # every entity a view names is in the file; the follow transform has one row per frame
    ents = read_entities(path)
    for v in views.values():
        for c in v["contents"]:
            if not c.endswith("**"):
                assert c in ents, c
    follow = read_rrd_table(path, "/follow")
    assert len(follow) == res.table.Frame_ID.nunique()
    probs = read_rrd_table(path, "/policy/action_probs")
    assert len(probs) == len(res.decisions)  # one bar chart per decision (the latest at a time is shown)


def test_blueprint_training_tab(tmp_path):
    from analysis.recording.blueprint import merge_blueprint

    path = tmp_path / "bp.rrd"
    rec, tmp = open_recording(path, recording_id="bp-test")
    log_training(rec, "qsm", np.array([-3.0, -2.0]), np.ones((2, 3)))
    rec.send_blueprint(merge_blueprint([5, 9], training_methods=["qsm", "reirl"], first_control=(10, 40)))
    close_recording(rec, tmp, path)
    views = {v["name"]: v for v in read_blueprint(path)}
    assert views["log-likelihood"]["contents"] == ["/train/qsm/loglik", "/train/reirl/loglik"]
    assert views["weights theta"]["contents"] == ["/train/qsm/theta/**", "/train/reirl/theta/**"]
    assert views["speed of A (ft/s)"]["contents"] == ["/metrics/A_5/speed", "/metrics/A_9/speed"]
    with pytest.raises(ValueError, match="no blueprint"):
        p2 = tmp_path / "plain.rrd"
        r2, t2 = open_recording(p2, recording_id="plain")
        log_training(r2, "qsm", np.array([-3.0]), np.ones((1, 3)))
        close_recording(r2, t2, p2)
        read_blueprint(p2)


@pytest.mark.sumo
def test_a_run_with_two_policies_holds_two_named_recordings(tmp_path):
    from analysis.evaluation.evaluate import evaluate

    rep = evaluate([], "synthetic", 1, 5, tmp_path / "eval", duration_s=90.0, baselines=("sumo", "uniform"),
                   workers=1, progress=False)
    files = sorted((tmp_path / "eval" / "rerun").glob("*.rrd"))
    assert [f.name for f in files] == ["sumo.rrd", "uniform.rrd"]
    infos = [recording_info(f) for f in files]
    assert [i["recording_id"][:-15] for i in infos] == ["merge-irl/synthetic/sumo/seed5", "merge-irl/synthetic/uniform/seed5"]
    assert [i["name"].split(" (run ")[0] for i in infos] == ["sumo on synthetic, seed 5", "uniform on synthetic, seed 5"]
    for f in files:
        assert {v["name"] for v in read_blueprint(f)} >= {"merge (follows car A)", "section", "speed of A (ft/s)"}
    # the SUMO baseline's As are observed, not driven: their own role and colour
    roles = np.concatenate(read_rrd_table(files[0], "/world/vehicles")["Boxes2D:class_ids"].to_numpy())
    assert (roles == ROLE_IDS["A observed"]).any() and not (roles == ROLE_IDS["A"]).any()
    roles = np.concatenate(read_rrd_table(files[1], "/world/vehicles")["Boxes2D:class_ids"].to_numpy())
    assert (roles == ROLE_IDS["A"]).any() and not (roles == ROLE_IDS["A observed"]).any()
    assert set(rep.rrd) == {"sumo", "uniform"}
    assert {p.name for p in rep.plots} >= {"speed_profiles.png", "acceleration.png", "headway.png"}


@pytest.mark.sumo
def test_screenshot_blueprint_is_recovered_from_the_recording(logged):
    from tools.render_screenshots import blueprint_inputs

    path, res = logged
    args = blueprint_inputs(path)
    c = res.controls.sort_values(["start_frame", "a_id"])
    assert args["a_ids"] == list(dict.fromkeys(int(a) for a in c.a_id))
    assert args["training_methods"] == []
    # the first take-over: from its first to its last logged frame; a car released and taken
    # over again in the next frame (another B) is one unbroken run of logged frames
    first = c.iloc[0]
    last_frame = int(res.table.Frame_ID.max())
    end = int(first.end_frame) if first.end_frame >= 0 else last_frame
    for r in c[(c.a_id == first.a_id) & (c.start_frame > first.start_frame)].itertuples():
        if r.start_frame <= end + 1:
            end = max(end, int(r.end_frame) if r.end_frame >= 0 else last_frame)
    assert args["first_control"][0] == int(first.start_frame)
    assert int(first.start_frame) < args["first_control"][1] <= end
    x0, x1, y0, y1 = args["section_bounds"]
    assert x0 < res.table.Global_X.min() and x1 > res.table.Global_X.max()
    assert y0 < -res.table.Global_Y.max() and y1 > -res.table.Global_Y.min()  # mirrored y
    assert args["play"] >= 4.0


def test_screenshot_tool_rejects_missing_files(tmp_path, capsys):
    from tools.render_screenshots import main

    assert main([str(tmp_path / "none.rrd")]) == 2
    assert "none.rrd" in capsys.readouterr().err


def test_bar_chart_column_matches_rerun_bar_charts(tmp_path):
    from analysis.recording.columns import bar_chart_column

    vals = np.random.default_rng(2).random((7, 5))
    a, b = tmp_path / "cols.rrd", tmp_path / "log.rrd"
    rec, tmp = open_recording(a, recording_id="cols")
    rec.send_columns("p", indexes=[rr.TimeColumn("step", sequence=np.arange(7))], columns=[bar_chart_column(vals)])
    close_recording(rec, tmp, a)
    rec, tmp = open_recording(b, recording_id="log")
    for i, v in enumerate(vals):
        rec.set_time("step", sequence=i)
        rec.log("p", rr.BarChart(v))
    close_recording(rec, tmp, b)
    ta, tb = read_rrd_table(a, "/p"), read_rrd_table(b, "/p")
    assert list(ta["BarChart:values"]) == list(tb["BarChart:values"])
    assert len(ta) == 7 and ta["BarChart:values"].iloc[3]["buffer"] == list(vals[3])


@pytest.mark.sumo
def test_the_merge_view_reads_at_a_glance(logged):
    """The road is drawn at its width with lanes, ramp and merge zone named, the merge view is
    zoomed to the merge, and the action probabilities are five bars named by action."""
    from analysis.recording.blueprint import FOLLOW_HALF_FT
    from irl.domains.merge.actions import ACTION_NAMES

    path, res = logged
    ents = read_entities(path)
    road = ents["/world/road"][0]
    assert len(road.column("LineStrips2D:strips")[0].as_py()) == 4
    assert road.column("LineStrips2D:radii")[0].as_py() == [6.0] * 4 or min(road.column("LineStrips2D:radii")[0].as_py()) > 5.0
    lane_labels = ents["/world/lanes"][0].column("LineStrips2D:labels")[0].as_py()
    assert "lane 7 (ramp / auxiliary lane)" in lane_labels and "lane 6 (right main lane)" in lane_labels
    marks = ents["/world/landmarks"][0].column("Points2D:labels")[0].as_py()
    assert marks == ["on-ramp", "merge zone: auxiliary lane begins", "auxiliary lane ends"]
    pos = np.asarray(ents["/world/landmarks"][0].column("Points2D:positions")[0].as_py())
    assert pos[0, 0] < pos[1, 0] < pos[2, 0]  # along the direction of travel
    names = ents["/policy/action_bars/names"][0].column("Points2D:labels")[0].as_py()
    assert names == [n.lower() for n in ACTION_NAMES]
    bars = read_rrd_table(path, "/policy/action_bars")
    bars = bars[bars["entity"] == "/policy/action_bars"]
    assert len(bars) == len(res.decisions)  # one set of five bars per decision
    heights = np.stack([2 * np.asarray(h.tolist())[:, 1] for h in bars["Boxes2D:half_sizes"]])  # [n, 5]
    probs = res.decisions[[f"p{i}" for i in range(5)]].to_numpy(float)
    np.testing.assert_allclose(np.sort(heights, axis=None), np.sort(probs, axis=None), atol=1e-6)
    labels = [list(x) for x in bars["Boxes2D:labels"]]
    assert all(len(x) == 5 for x in labels) and labels[0] == [f"{h:.2f}" for h in heights[0]]
    assert FOLLOW_HALF_FT[0] <= 200.0  # about 350 ft of road: lanes and cars readable


def _roles_by_row(path):
    """{(step, Vehicle_ID): (class id, label)} of ``/world/vehicles``."""
    out = {}
    for b in read_entities(path)["/world/vehicles"]:
        for s, ids, cls, lab in zip(b.column("step").to_pylist(), b.column("vehicle_id").to_pylist(),
                                    b.column("Boxes2D:class_ids").to_pylist(), b.column("Boxes2D:labels").to_pylist()):
            out.update({(int(s), int(v)): (int(k), lb) for v, k, lb in zip(ids, cls, lab)})
    return out


@pytest.mark.sumo
def test_roles_and_labels_do_not_depend_on_the_buffer(tmp_path):
    """Roles and labels are built per buffer when it is sent: a buffer of 7 frames (many sends,
    the controller's rows offset in each) logs what one of 600 does; without a controller the
    ramp lane's vehicles are B."""
    from analysis.recording.log import RerunLogger
    from sim.closed_loop.controller import Controller
    from sim.runtime.run import run_scenario

    spec = load_scenario("synthetic")
    q = np.random.default_rng(7).normal(size=(1250, 5))
    policy = LearnedPolicy(q - np.log(np.exp(q).sum(axis=1, keepdims=True)), MergeBins.from_dict(EDGES), name="random-q")
    logged = {}
    for every in (7, 600):
        ctl = Controller(policy)
        path = tmp_path / f"every{every}.rrd"
        run_scenario(spec, duration_s=120.0, hooks=[ctl, RerunLogger(path, controller=ctl, flush_every=every)])
        logged[every] = _roles_by_row(path)
    assert logged[7] == logged[600]
    assert {k for k, _ in logged[7].values()} >= {ROLE_IDS["A"], ROLE_IDS["B"], ROLE_IDS["C"]}
    path = tmp_path / "no-controller.rrd"
    res = run_scenario(spec, duration_s=120.0, hooks=[RerunLogger(path, flush_every=7)])
    roles = _roles_by_row(path)
    lane = dict(zip(zip(res.table.Frame_ID, res.table.Vehicle_ID), res.table.Lane_ID))
    assert roles.keys() == lane.keys()
    ramp = [k for k, v in lane.items() if v == 7]
    assert ramp and all(roles[k] == (ROLE_IDS["B"], f"B {k[1]}") for k in ramp)
    assert all(roles[k] == (ROLE_IDS["other"], "") for k, v in lane.items() if v != 7)
