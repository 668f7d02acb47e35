"""The seeds both environments' ``reset`` accept (:mod:`sim.env.seeds`): any integer >= 0 (numpy's
and 64-bit ones included) mapped into SUMO's range, small seeds unchanged; bool, float, negative
and other types refused in one line naming the seed; and, on real SUMO, MergeEnv and the
PettingZoo environment refusing and accepting the same seeds."""

from __future__ import annotations

import numpy as np
import pytest

from sim.env.seeds import COLLECTOR_OPTIONS, SUMO_SEED_LIMIT, SeedError, reset_seed, sumo_seed, unread_options

BIG = 2**63 + 5


def test_small_seeds_keep_their_meaning_and_large_ones_map_into_sumos_range() -> None:
    for s in (0, 1, 101, 3001, SUMO_SEED_LIMIT - 1):
        assert reset_seed(s, "x") == (s, s)
    for s in (SUMO_SEED_LIMIT, BIG, 2**64 - 1, 10**40):
        r = reset_seed(s, "x")
        assert r is not None and r.seed == s and 0 <= r.sumo < SUMO_SEED_LIMIT
        assert r.sumo == sumo_seed(s)  # deterministic: the same seed, the same SUMO seed
    # the documented hash, pinned: a change of the mapping changes every large-seed run
    assert sumo_seed(BIG) == 865983082 and sumo_seed(2**64 - 1) == 1327767473
    assert sumo_seed(BIG) != sumo_seed(BIG + 1)
    mapped = {sumo_seed(2**40 + i) for i in range(200)}
    assert len(mapped) == 200  # spread: no collisions among 200 neighbours


def test_numpy_integers_are_python_ints_after_the_check() -> None:
    for s in (np.uint64(2**64 - 1), np.int64(7), np.uint8(3), np.int32(SUMO_SEED_LIMIT - 1)):
        r = reset_seed(s, "x")
        assert r is not None and type(r.seed) is int and type(r.sumo) is int and r.seed == int(s)
    assert reset_seed(np.uint64(2**64 - 1), "x") == reset_seed(2**64 - 1, "x")
    assert reset_seed(None, "x") is None


@pytest.mark.parametrize("bad, shown", [(-1, "got -1"), (np.int64(-3), "got -3"), (9.7, "got 9.7 (float)"),
                                        (9.0, "got 9.0 (float)"), (True, "got True (bool)"),
                                        (np.bool_(False), "got np.False_"), ("5", "got '5' (str)"),
                                        (np.float64(2.0), "(float64)")])
def test_bool_float_negative_and_other_types_are_refused_in_one_line(bad, shown) -> None:
    with pytest.raises(SeedError, match=r"^MergeEnv\.reset: seed must be an integer >= 0") as e:
        reset_seed(bad, "MergeEnv.reset")
    assert shown in str(e.value) and "\n" not in str(e.value)
    assert isinstance(e.value, ValueError) and isinstance(e.value, TypeError)


def test_the_collectors_own_options_are_not_the_environments() -> None:
    assert "minari_autoseed" in COLLECTOR_OPTIONS
    assert unread_options(None) == [] and unread_options({}) == []
    assert unread_options({"minari_autoseed": False}) == []
    assert unread_options({"minari_autoseed": True, "scenario": "i80", 3: 1}) == ["3", "scenario"]


@pytest.mark.sumo
def test_both_environments_accept_and_refuse_the_same_seeds() -> None:
    pytest.importorskip("pettingzoo")
    from sim.env import MergeEnv
    from sim.env.multi_agent import MergeParallelEnv

    single, multi = MergeEnv(run_s=240.0), MergeParallelEnv(run_s=240.0)
    try:
        for env, where in ((single, "MergeEnv.reset"), (multi, "MergeParallelEnv.reset")):
            for bad in (-1, 9.7, True):
                with pytest.raises(SeedError, match=rf"^{where}: seed must be an integer >= 0 .*got {bad}"):
                    env.reset(seed=bad)
        _, info = single.reset(seed=np.uint64(2**64 - 1))
        assert info["seed"] == sumo_seed(2**64 - 1)
        _, infos = multi.reset(seed=2**64 - 1)
        assert {i["seed"] for i in infos.values()} == {sumo_seed(2**64 - 1)}
        # a small seed is the SUMO seed itself, as before
        _, info = single.reset(seed=5)
        assert info["seed"] == 5
    finally:
        single.close()
        multi.close()
