"""The demo's configuration: held-out runs and seed overlaps, checked before any work."""

from __future__ import annotations

import pytest

from analysis.cli.main import main
from analysis.demo.config import WITH_DAGGER_ROUNDS, DemoConfig, check_dagger_seeds
from irl.errors import ConfigError
from sim.errors import SimError


def test_heldout_runs_are_consecutive_seeds_apart_from_the_training_seeds():
    assert DemoConfig().heldout_seeds == (201,)
    assert DemoConfig(heldout_seed=5, heldout_runs=3).heldout_seeds == (5, 6, 7)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ConfigError, match="heldout_runs"):
            DemoConfig(heldout_runs=bad)
    with pytest.raises(ConfigError, match=r"\[103\].*training and held-out"):
        DemoConfig(train_seeds=(101, 102, 103), heldout_seed=103)
    with pytest.raises(ConfigError, match=r"\[101, 102\].*held-out: 97\.\.102"):
        DemoConfig(train_seeds=(101, 102, 103), heldout_seed=97, heldout_runs=6)
    import numpy as np

    assert DemoConfig(heldout_runs=np.int64(2)).heldout_seeds == (201, 202)
    for kw in ({"heldout_seed": -1}, {"heldout_seed": 201.5}, {"heldout_seed": "201"}, {"eval_duration_s": 0.0},
               {"eval_duration_s": float("nan")}, {"eval_duration_s": float("inf")}, {"eval_duration_s": "60"}):
        with pytest.raises(ConfigError):
            DemoConfig(**kw)
    # data seeds may not be evaluation seeds: the drivers would be scored on their demonstrations' traffic
    with pytest.raises(ConfigError, match=r"\[2, 3\].*evaluation: 1\.\.3"):
        DemoConfig(heldout_seed=2, heldout_runs=5, eval_episodes=3)
    with pytest.raises(ConfigError, match=r"\[101\]"):
        DemoConfig(eval_seed=95, eval_episodes=7)


def test_dagger_labelling_seeds_may_not_be_held_out_seeds():
    check_dagger_seeds(DemoConfig(dagger_rounds=1, heldout_seed=201, heldout_runs=10))  # 500.. is free
    with pytest.raises(SimError, match="overlap"):
        check_dagger_seeds(DemoConfig(dagger_rounds=1, heldout_seed=495, heldout_runs=10))  # 495..504 vs 500..514
    with pytest.raises(SimError, match="500..514"):
        check_dagger_seeds(DemoConfig(dagger_rounds=1, eval_seed=510, eval_episodes=30))  # evaluation 510..539
    check_dagger_seeds(DemoConfig(dagger_rounds=1, eval_seed=515, eval_episodes=30))
    # seed ranges are compared as ranges: a huge count is checked at once (a set of every seed
    # filled the machine's memory)
    check_dagger_seeds(DemoConfig(dagger_rounds=10**12))
    with pytest.raises(SimError, match="overlap"):
        check_dagger_seeds(DemoConfig(dagger_rounds=10**12, eval_seed=10**9, eval_episodes=10**12))
    with pytest.raises(ConfigError, match=r"\[101, 102, 103, 201\]"):
        DemoConfig(eval_episodes=10**12)


def test_cli_rejects_a_bad_heldout_count_before_any_run(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["demo", "--heldout-runs", "0", "--out", str(tmp_path / "d")])
    assert e.value.code == 2 and "--heldout-runs" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_the_demo_says_how_long_it_will_take():
    """One line before any work: longer on a busy machine, shorter without DAgger, in a range
    that holds the measured demos whose load held during the run."""
    from analysis.demo.estimate import CPU_PER_SIM_S, CPU_PER_SIM_S_PER_LOAD, MEASURED, estimate, simulated_seconds
    from scenarios.loader import load_scenario

    spec = load_scenario("synthetic")
    cfg = DemoConfig(dagger_rounds=WITH_DAGGER_ROUNDS)  # merge-irl demo --with-dagger
    # the model's simulated seconds are those of the measured runs, and its CPU time theirs within 10 %
    assert simulated_seconds(cfg, spec) == MEASURED[0][1] == MEASURED[2][1]
    assert simulated_seconds(DemoConfig(), spec) == MEASURED[1][1]  # the default demo: no DAgger
    for _, sim_s, cpu_s, _, load in MEASURED:
        assert abs((CPU_PER_SIM_S + CPU_PER_SIM_S_PER_LOAD * load) * sim_s - cpu_s) / cpu_s < 0.1
    idle = estimate(cfg, spec, cores=2, load=0.0)
    busy = estimate(cfg, spec, cores=2, load=11.4)
    short = estimate(DemoConfig(dagger_rounds=0), spec, cores=2, load=0.0)
    assert idle.wall_s == idle.cpu_s / 2 and busy.wall_s > 5 * idle.wall_s and short.wall_s < idle.wall_s / 3
    for i, load in ((1, 11.4), (2, 2.5)):  # the two whose load held; their load at the start
        _, _, _, wall, _ = MEASURED[i]
        e = estimate(DemoConfig(dagger_rounds=0) if i == 1 else cfg, spec, cores=2, load=load)
        assert 0.75 * e.wall_s <= wall <= 2.0 * e.wall_s, (i, e)
    line = busy.line()
    assert "\n" not in line and line.startswith("merge-irl demo: expect about") and "load average now 11.4" in line
    assert "cores idle" in idle.line()


@pytest.mark.parametrize(("flags", "rounds"), [((), 0), (("--with-dagger",), WITH_DAGGER_ROUNDS),
                                               (("--dagger-rounds", "2"), 2)])
def test_cli_trains_cf_dagger_only_when_asked(tmp_path, monkeypatch, flags, rounds):
    """The default demo leaves DAgger's labelling runs out; --with-dagger (or --dagger-rounds N) adds them."""
    import analysis.cli.commands.demo as demo_cmd

    seen: list[DemoConfig] = []

    def fake_run_demo(out, config, **kw):
        seen.append(config)
        raise KeyboardInterrupt  # stop before any work; the CLI exits 130

    monkeypatch.setattr(demo_cmd, "run_demo", fake_run_demo)
    code = main(["demo", *flags, "--out", str(tmp_path / "d")])
    assert code == 130 and [c.dagger_rounds for c in seen] == [rounds]


def test_cli_rejects_with_dagger_beside_dagger_rounds(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["demo", "--with-dagger", "--dagger-rounds", "2", "--out", str(tmp_path / "d")])
    assert e.value.code == 2 and "--dagger-rounds" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()
