"""The evaluation plots: demonstrations as reference, counts, one colour per policy, marks."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from matplotlib.colors import to_rgba

import analysis.evaluation.plots as rp
from analysis.evaluation.heldout_scoring import HeldOut
from analysis.evaluation.palette import POLICY_COLORS, policy_color


def _result(rng: np.random.Generator, n_controls: int, v0: float, jump: bool = False):
    """An EpisodeResult-like object: controls, decisions, speed_profiles of ``n_controls`` As."""
    controls = pd.DataFrame({"a_id": np.arange(n_controls), "merge_frame": np.where(np.arange(n_controls) % 4 == 3, -1, 50),
                             "gap_AB_start_ft": rng.uniform(-30, 250, n_controls), "b_ahead": rng.random(n_controls) < 0.6})
    prof = []
    for a in range(n_controls):
        t = np.arange(60) * 0.1
        v = v0 + np.cumsum(rng.normal(0, 0.3, 60))
        if jump and a == 0:
            v[30:] += 120.0  # a speed far above the limit, reached by a 1200 ft/s^2 step
            v[45:] -= 130.0  # braking far beyond 1 g
        prof.append(pd.DataFrame({"a_id": a, "t_s": t, "v_ft_s": v}))
    decisions = pd.DataFrame({"d_AC": np.where(rng.random(5 * n_controls) < 0.2, np.nan, rng.gamma(3, 30, 5 * n_controls))})
    return SimpleNamespace(controls=controls, decisions=decisions, speed_profiles=pd.concat(prof, ignore_index=True))


def _held(rng: np.random.Generator, n_enc: int = 12) -> HeldOut:
    rows = []
    for e in range(1, n_enc + 1):
        d0 = rng.uniform(-20, 220)
        for f in range(20):
            rows.append({"encounter_id": e, "Frame_ID": 100 * e + f, "merge_frame": 100 * e + 10, "d_AB": d0 + 3 * f - 20,
                         "d_AC": rng.uniform(20, 200), "acc_A": rng.normal(0, 3)})
    enc = pd.DataFrame(rows)
    return HeldOut(enc, np.array([3, 10, 200, 20, 7]), "synthetic")


def _handle_color(h) -> tuple:
    """RGBA of a legend handle: a line's colour, a bar's face, a step histogram's edge."""
    if hasattr(h, "get_color") and not hasattr(h, "get_facecolor"):
        return to_rgba(h.get_color())
    fc = to_rgba(h.get_facecolor())
    return fc if fc[3] > 0 else to_rgba(h.get_edgecolor())


@pytest.fixture
def figures(monkeypatch):
    """Captures every figure the plots save: path name -> (legend texts, line colours by label)."""
    seen = {}
    real = rp._save

    def capture(fig, path):
        texts, colors = [], {}
        visible = [ax for ax in fig.axes if ax.get_visible()]
        for ax in visible:
            leg = ax.get_legend()
            for h, t in zip(leg.legend_handles if leg is not None else [], leg.get_texts() if leg is not None else []):
                if t.get_text() not in texts:
                    texts.append(t.get_text())
                colors[t.get_text().split(" (")[0]] = _handle_color(h)
        title = fig.get_suptitle() or visible[0].get_title()
        panels = {ax.get_title(): ax for ax in visible}
        seen[path.name] = (texts, colors, title, panels)
        return real(fig, path)

    monkeypatch.setattr(rp, "_save", capture)
    return seen


def _policies():
    rng = np.random.default_rng(3)
    by = {"qavg": [_result(rng, 8, 80.0), _result(rng, 6, 82.0)], "reirl": [_result(rng, 5, 90.0, jump=True)],
          "sumo": [_result(rng, 7, 85.0)]}
    aggs = {k: SimpleNamespace(action_counts=tuple(rng.integers(1, 50, 5))) for k in by}
    return by, aggs


def test_plots_with_demonstrations(tmp_path, figures):
    by, aggs = _policies()
    held = _held(np.random.default_rng(4))
    paths = rp.write_plots(tmp_path, aggs, by, held, speed_limit_ft_s=95.0)
    assert {p.name for p in paths} == {"action_histograms.png", "gap_acceptance.png", "speed_profiles.png",
                                       "acceleration.png", "headway.png"}
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the demonstrations are the reference of every plot that has them (the encounter table
    # holds no absolute speed: the speed plot says so instead)
    for name in ("action_histograms.png", "gap_acceptance.png", "acceleration.png", "headway.png"):
        assert figures[name][0][0].startswith("demonstrations (n="), name
    assert "no absolute speed" in figures["speed_profiles.png"][2]
    # sample counts: 12 demonstrated encounters; qavg merged in 14 - 3 control episodes
    gap = figures["gap_acceptance.png"][0]
    assert "demonstrations (n=12 merges)" in gap
    assert "qavg (n=11 merges)" in gap and "reirl (n=4 merges)" in gap
    assert "demonstrations (n=240 decisions)" in figures["action_histograms.png"][0]
    # one colour per policy, the same in every plot
    for name, (_, colors, _, _) in figures.items():
        for pol in ("qavg", "reirl", "sumo", "demonstrations"):
            if pol in colors:
                np.testing.assert_allclose(colors[pol][:3], to_rgba(policy_color(pol))[:3], err_msg=f"{pol} in {name}")
    # implausible values are marked and counted: reirl's jump of 120 ft/s over the limit and its
    # braking of 1300 ft/s^2
    speed = " ".join(figures["speed_profiles.png"][0])
    assert "reirl (n=5 take-overs, 15 samples implausible)" in speed and "implausible above 124 ft/s" in speed
    acc = [t for t in figures["acceleration.png"][0] if t.startswith("braking beyond 1 g")]
    assert acc == ["braking beyond 1 g (-32.2 ft/s^2): reirl 1"]


def test_plots_without_demonstrations(tmp_path, figures):
    by, aggs = _policies()
    paths = rp.write_plots(tmp_path, aggs, by, None)
    assert all(p.exists() for p in paths)
    for name, (texts, _, title, _) in figures.items():
        assert not any(t.startswith("demonstrations") for t in texts), name
        assert "no absolute speed" not in title
    # default limit: 29 m/s
    assert any("implausible above 124 ft/s" in t for t in figures["speed_profiles.png"][0])


def test_plots_without_any_data(tmp_path, figures):
    paths = rp.write_plots(tmp_path, {}, {"qavg": []}, None)
    assert all(p.exists() for p in paths)


def test_demo_merges_and_accelerations():
    held = _held(np.random.default_rng(4), 3)
    m = rp.demo_merges(held)
    e = held.encounters
    first = e.groupby("encounter_id").d_AB.first().to_numpy()
    np.testing.assert_allclose(m.gap_AB_start_ft, first)
    at_merge = e[e.Frame_ID == e.merge_frame].d_AB.to_numpy()
    np.testing.assert_array_equal(m.b_ahead, at_merge > 0)
    r = SimpleNamespace(speed_profiles=pd.DataFrame({"a_id": [1, 1, 1, 2, 2], "t_s": [0, 0.1, 0.2, 0, 0.1],
                                                     "v_ft_s": [10.0, 11.0, 10.5, 20.0, 19.0]}))
    np.testing.assert_allclose(rp.policy_accelerations([r]), [10.0, -5.0, -10.0])


def test_palette_is_fixed_and_covers_the_baselines():
    for name in ("uniform", "marginal", "markov", "bc", "sumo", "qavg", "qsm", "mlirl", "reirl"):
        assert name in POLICY_COLORS
    assert len(set(POLICY_COLORS.values())) == len(POLICY_COLORS)
    assert policy_color("qavg-2") == policy_color("qavg-2") and policy_color("qavg-2") not in POLICY_COLORS.values()


def test_demo_merges_without_merge_frame_use_the_last_frame():
    held = _held(np.random.default_rng(5), 4)
    bare = HeldOut(held.encounters.drop(columns=["merge_frame"]), held.action_counts, "bare")
    m = rp.demo_merges(bare)
    last = bare.encounters.groupby("encounter_id").d_AB.last().to_numpy()
    np.testing.assert_array_equal(m.b_ahead, last > 0)
    assert rp.demo_merges(HeldOut(bare.encounters[["acc_A"]], held.action_counts)).empty


def _legend_texts(ax) -> list[str]:
    leg = ax.get_legend()
    return [t.get_text() for t in leg.get_texts()] if leg is not None else []


def test_band_plots_have_one_panel_per_policy_against_the_demonstrations(tmp_path, figures):
    """Eight policies on one axis smear the bands: gap acceptance and speed profiles are small
    multiples, one panel per policy (titled by it, in its colour), each with the demonstrations."""
    rng = np.random.default_rng(7)
    names = ["planner", "cf-dagger", "cf-logit", "qavg", "sumo", "uniform", "marginal", "markov", "bc"]
    by = {n: [_result(rng, 6, 80.0 + i)] for i, n in enumerate(names)}
    aggs = {k: SimpleNamespace(action_counts=tuple(rng.integers(1, 50, 5))) for k in by}
    held = _held(np.random.default_rng(4))
    held.encounters["v_A"] = 80.0
    rp.write_plots(tmp_path, aggs, by, held)
    for plot in ("gap_acceptance.png", "speed_profiles.png"):
        panels = figures[plot][3]
        assert sorted(panels) == sorted(names), plot
        for name, ax in panels.items():
            labels = [t.split(" (")[0] for t in _legend_texts(ax)]
            assert labels[:2] == ["demonstrations", name], (plot, name, labels)
            assert to_rgba(ax.title.get_color()) == to_rgba(policy_color(name))
        assert "one panel per policy" in figures[plot][2]


def test_learned_drivers_have_strong_distinct_colours():
    """The drivers the demo learns and the references have saturated colours of their own (they
    took pale hash colours before, and planner shared cf-logit's)."""
    from matplotlib.colors import rgb_to_hsv, to_rgb

    strong = ("planner", "cf-dagger", "cf-logit", "qavg", "sumo", "sumo-in-lane", "idm")
    colours = [policy_color(n) for n in strong]
    assert len(set(colours)) == len(strong)
    for name in strong:
        _, saturation, value = rgb_to_hsv(to_rgb(policy_color(name)))
        assert saturation >= 0.5 and value <= 0.85, (name, policy_color(name))
    assert len(set(POLICY_COLORS.values())) == len(POLICY_COLORS)
