"""The merge domain (irl.domains.merge.actions, _states, _bins, _encounters, _features) at its edges: NaN, bin boundaries, +-inf, scalar vs vectorised."""

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from irl.domains.merge.actions import (
    ACTION_ACC_FT_S2,
    ACTION_NAMES,
    N_ACTIONS,
    ZERO_ACTION,
    action_of,
    actions_of,
    forward_acceleration,
)
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.encounters import (
    ENCOUNTER_COLUMNS,
    ENCOUNTER_SCHEMA,
    ENCOUNTER_UNITS,
    REQUIRED_COLUMNS,
    validate_encounters,
)
from irl.domains.merge.features import features, paper_features
from irl.domains.merge.states import DESCENDING, N_STATES, SAFE_DISTANCE_FT, VARIABLES, state_index, state_parts
from irl.errors import ConfigError, DemonstrationError, EncodingError
from merge_irl.units import FRAME_S, FT_PER_M, M_PER_FT

BINS = MergeBins.assumed_authors()  # d_AC (35, 60, 90, 130), d_AB (10, 30, 60, 100), v (-7.5, -2.5, 2.5, 7.5)
NAN = math.nan


def test_units():
    assert M_PER_FT == 0.3048 and FT_PER_M * M_PER_FT == pytest.approx(1.0, abs=1e-15) and FRAME_S == 0.1


def test_state_layout_round_trip():
    s = np.arange(N_STATES)
    parts = state_parts(s)
    np.testing.assert_array_equal(state_index(*parts.T), s)
    assert state_index(1, 4, 0, 0, 0) == 625 + 500


# -- actions ---------------------------------------------------------------------------

def test_action_bins_at_the_boundaries_and_beyond():
    acc = [-math.inf, -20, -11.2, -4.8, -4.79, -0.6, -0.59, 0.0, 0.59, 0.6, 4.79, 4.8, 11.2, 30, math.inf]
    expected = [0, 0, 0, 0, 1, 1, 2, 2, 2, 3, 3, 4, 4, 4, 4]
    np.testing.assert_array_equal(actions_of(acc), expected)
    assert [action_of(a) for a in acc] == expected
    assert actions_of(np.array(acc).reshape(3, 5)).shape == (3, 5)
    # each action's applied acceleration lies in its own bin
    np.testing.assert_array_equal(actions_of(ACTION_ACC_FT_S2), np.arange(N_ACTIONS))
    assert len(ACTION_NAMES) == N_ACTIONS and ACTION_NAMES[ZERO_ACTION] == "Zero"


def test_nan_acceleration_is_an_error_in_both_paths():
    with pytest.raises(EncodingError, match="NaN"):
        action_of(NAN)
    with pytest.raises(EncodingError, match="flat index 2"):
        actions_of([0.0, 1.0, NAN])
    assert issubclass(EncodingError, DemonstrationError) and issubclass(EncodingError, ValueError)


@given(st.floats(allow_nan=False))
def test_scalar_and_vectorised_actions_agree(a):
    assert action_of(a) == int(actions_of(a))


def test_forward_acceleration():
    np.testing.assert_allclose(forward_acceleration([50.0, 51.0], [51.0, 50.5]), [10.0, -5.0])
    assert forward_acceleration(10.0, 13.0, dt=0.3) == pytest.approx(10.0)


# -- states ----------------------------------------------------------------------------

def test_state_bins_at_the_edges():
    # a value on an edge falls in the bin above it; d_AC counts from the far end
    assert [int(BINS.bin_index("d_AC", v)) for v in (34.999, 35.0, 60.0, 90.0, 130.0, math.inf, -math.inf)] == [4, 3, 2, 1, 0, 0, 4]
    assert [int(BINS.bin_index("d_AB", v)) for v in (-math.inf, 9.99, 10.0, 30.0, 60.0, 100.0, math.inf)] == [0, 0, 1, 2, 3, 4, 4]
    assert [int(BINS.bin_index("v_AC", v)) for v in (-7.5, -2.5, 0.0, 2.5, 7.5)] == [1, 2, 2, 3, 4]
    with pytest.raises(EncodingError, match="d_AB is NaN"):
        BINS.bin_index("d_AB", [1.0, NAN])
    # scalar and vectorised agree on edges and infinities
    for d_ac in (35.0, 130.0, math.inf, -math.inf):
        for v in (-7.5, 7.5, math.inf, -math.inf):
            assert BINS.state(d_ac, 10.0, v, v, True) == int(BINS.states(d_ac, 10.0, v, v, True))


def test_no_lead_car_rule():
    # no car C: d_AC and v_AC NaN -> the farthest d_AC bin and the v_AC bin of zero relative speed
    s = BINS.state(NAN, 20.0, NAN, 1.0, False)
    assert s == BINS.state(math.inf, 20.0, 0.0, 1.0, False)
    assert tuple(state_parts(s)) == (0, 0, 1, 2, 2)
    assert BINS.no_lead_v_AC_bin() == 2
    np.testing.assert_array_equal(BINS.states([NAN, 200.0], [20.0, 20.0], [NAN, 0.0], [1.0, 1.0], [0, 0]), [s, s])
    # the zero-speed bin follows the edges: all edges negative -> the top bin
    shifted = MergeBins(d_AC=BINS.d_AC, d_AB=BINS.d_AB, v_AC=(-4.0, -3.0, -2.0, -1.0), v_AB=BINS.v_AB)
    assert shifted.no_lead_v_AC_bin() == 4 == state_parts(shifted.state(NAN, 0.0, NAN, 0.0, False))[3]


@pytest.mark.parametrize("args", [
    (NAN, 20.0, 1.0, 1.0, False),    # d_AC NaN alone
    (50.0, 20.0, NAN, 1.0, False),   # v_AC NaN alone
    (50.0, NAN, 1.0, 1.0, False),    # d_AB NaN
    (50.0, 20.0, 1.0, NAN, False),   # v_AB NaN
    (50.0, 20.0, 1.0, 1.0, NAN),     # truck flag NaN
])
def test_nan_outside_the_no_lead_rule_is_an_error(args):
    with pytest.raises(EncodingError):
        BINS.state(*args)
    with pytest.raises(EncodingError):
        BINS.states(*([a] for a in args))


finite_or_inf = st.floats(allow_nan=False, min_value=-1e6, max_value=1e6) | st.sampled_from(
    [math.inf, -math.inf, 35.0, 60.0, 90.0, 130.0, 10.0, 30.0, 100.0, -7.5, -2.5, 2.5, 7.5])


@settings(max_examples=300)
@given(d_ac=finite_or_inf, d_ab=finite_or_inf, v_ac=finite_or_inf, v_ab=finite_or_inf, truck=st.booleans(),
       no_c=st.booleans())
def test_scalar_and_vectorised_encoders_agree(d_ac, d_ab, v_ac, v_ab, truck, no_c):
    if no_c:
        d_ac = v_ac = NAN
    s = BINS.state(d_ac, d_ab, v_ac, v_ab, truck)
    assert 0 <= s < N_STATES
    assert s == int(BINS.states(d_ac, d_ab, v_ac, v_ab, truck))
    df = pd.DataFrame({"d_AC": [d_ac], "d_AB": [d_ab], "v_AC": [v_ac], "v_AB": [v_ab], "B_is_truck": [truck]})
    assert s == int(BINS.encode(df)[0])


def test_vectorised_encoder_on_many_rows_matches_the_bin_definition():
    rng = np.random.default_rng(0)
    n = 2000
    cols = {"d_AC": rng.uniform(0, 200, n), "d_AB": rng.uniform(-50, 150, n), "v_AC": rng.normal(0, 8, n),
            "v_AB": rng.normal(0, 8, n)}
    cols["d_AC"][:4] = [35.0, 60.0, 90.0, 130.0]
    cols["v_AB"][:4] = [-7.5, -2.5, 2.5, 7.5]
    truck = rng.random(n) < 0.5
    s = BINS.states(cols["d_AC"], cols["d_AB"], cols["v_AC"], cols["v_AB"], truck)
    parts = state_parts(s)
    for i, name in enumerate(VARIABLES):
        e = np.asarray(getattr(BINS, name))
        idx = 4 - parts[:, i + 1] if name in DESCENDING else parts[:, i + 1]
        v = cols[name]
        assert np.all(v >= np.r_[-np.inf, e][idx]) and np.all(v < np.r_[e, np.inf][idx])
    np.testing.assert_array_equal(parts[:, 0], truck)
    assert [BINS.state(*r) for r in zip(*cols.values(), truck)] == s.tolist()


def test_bins_json_round_trip_and_validation(tmp_path):
    p = BINS.save(tmp_path / "bins.json")
    assert MergeBins.load(p) == BINS
    with pytest.raises(ConfigError, match="strictly increasing"):
        MergeBins(d_AC=(1, 1, 2, 3), d_AB=(0, 1, 2, 3), v_AC=(0, 1, 2, 3), v_AB=(0, 1, 2, 3))
    with pytest.raises(ConfigError, match="finite"):
        MergeBins(d_AC=(1, 2, 3, math.inf), d_AB=(0, 1, 2, 3), v_AC=(0, 1, 2, 3), v_AB=(0, 1, 2, 3))
    with pytest.raises(ConfigError, match=r"missing variable\(s\) \['v_AB'\]"):
        MergeBins.from_dict({"d_AC": [1, 2, 3, 4], "d_AB": [1, 2, 3, 4], "v_AC": [1, 2, 3, 4]})


# -- encounter table -------------------------------------------------------------------

def _table(n=50, seed=0):
    rng = np.random.default_rng(seed)
    return pd.DataFrame({"encounter_id": np.repeat([1, 2], n // 2), "d_AC": rng.uniform(5, 200, n),
                         "d_AB": rng.uniform(-20, 120, n), "v_AC": rng.normal(0, 6, n), "v_AB": rng.normal(0, 6, n),
                         "B_is_truck": rng.random(n) < 0.3, "acc_A": rng.normal(0, 4, n)})


def test_schema_is_documented_and_consistent():
    assert list(ENCOUNTER_COLUMNS) == [c.name for c in ENCOUNTER_SCHEMA]
    assert set(REQUIRED_COLUMNS) <= set(ENCOUNTER_COLUMNS)
    assert ENCOUNTER_UNITS["d_AC"] == "ft" and ENCOUNTER_UNITS["acc_A"] == "ft/s^2"
    assert all(c.doc for c in ENCOUNTER_SCHEMA)
    assert "forward difference" in dict((c.name, c.doc) for c in ENCOUNTER_SCHEMA)["acc_A"]


def test_validate_encounters():
    df = _table()
    df.loc[[0, 9], ["d_AC", "v_AC"]] = NAN  # no car C: allowed
    validate_encounters(df)
    for col, val in (("v_AB", math.inf), ("acc_A", NAN), ("d_AC", -math.inf), ("v_AC", NAN)):
        bad = df.copy()
        bad.loc[4, col] = val
        with pytest.raises(DemonstrationError, match=rf"row 4, column '{col}'"):
            validate_encounters(bad, "t.parquet")
    with pytest.raises(DemonstrationError, match="no rows"):
        validate_encounters(df.iloc[:0])


def test_quantile_bins_with_and_without_car_c():
    df = _table(200)
    bins = fit_quantile_bins(df)
    assert bins.d_AC[0] == SAFE_DISTANCE_FT
    for name in ("d_AB", "v_AC", "v_AB"):
        counts = np.bincount(bins.bin_index(name, df[name]), minlength=5)
        assert np.all(np.abs(counts - len(df) / 5) <= 2)  # quantile bins: equal counts
    df.loc[:99, ["d_AC", "v_AC"]] = NAN  # half the frames without C: edges from the others
    half = fit_quantile_bins(df)
    np.testing.assert_allclose(half.v_AC, np.quantile(df.v_AC[100:], [0.2, 0.4, 0.6, 0.8]))
    df[["d_AC", "v_AC"]] = NAN  # no C anywhere
    none = fit_quantile_bins(df)
    assert none.v_AC == MergeBins.assumed_authors().v_AC and none.d_AC == (35.0, 45.0, 55.0, 65.0)


# -- features --------------------------------------------------------------------------

def test_features_match_the_paper_and_the_continuous_form():
    phi = features()
    assert phi.shape == (1250, 5, 3)
    for s in range(0, 1250, 7):
        truck, x1 = state_parts(s)[:2]
        for a in range(5):
            assert phi[s, a, 0] == (0 if (x1 == 4 and a >= 3) else 1)
            assert phi[s, a, 1] == (1 if a >= 2 else 0)
            assert phi[s, a, 2] == (1 if (truck == 1 and a >= 3) else 0)
    # the continuous form agrees with the table under bins whose smallest d_AC edge is 35 ft
    for d_ac in (NAN, 10.0, 34.9, 35.0, 200.0):
        for truck in (False, True):
            v_ac = NAN if math.isnan(d_ac) else 0.0
            s = BINS.state(d_ac, 20.0, v_ac, 0.0, truck)
            for a in range(5):
                assert paper_features(d_ac, truck, a) == tuple(phi[s, a])
