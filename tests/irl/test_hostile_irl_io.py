"""Hostile input for the demonstration loaders (``irl.io``): the authors' text format and the
generic ``.npz``. Random or malformed files give a ``DemonstrationError`` naming the file, or
valid ``Demonstrations``; never a numpy/zipfile exception, never a hang."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from irl.demonstrations import Demonstrations
from irl.errors import DemonstrationError
from irl.io import load_npz, load_text_trajectories, save_npz

pytestmark = pytest.mark.hostile

SETTINGS = settings(max_examples=120, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
S, A, K = 5, 3, 2
FEATS = np.linspace(-1, 1, S * A * K).reshape(S, A, K)


def _valid(d: Demonstrations, n_states: int, n_actions: int):
    assert d.n_trajectories >= 1
    for s, a in zip(d.states, d.actions):
        assert s.size == a.size >= 1
        assert s.min() >= 0 and s.max() < n_states and a.min() >= 0 and a.max() < n_actions
    assert np.all(np.isfinite(d.features))


def _check_text(path, n_states=S, n_actions=A, features=FEATS):
    try:
        d = load_text_trajectories(path, n_states=n_states, n_actions=n_actions, features=features)
    except DemonstrationError as e:
        assert str(path) in str(e) or path.name in str(e)
        return None
    _valid(d, n_states, n_actions)
    return d


def _check_npz(path):
    try:
        d = load_npz(path)
    except DemonstrationError as e:
        assert str(path) in str(e)
        return None
    _valid(d, d.n_states, d.n_actions)
    return d


line = st.one_of(
    st.tuples(st.integers(-2, S + 1), st.integers(-2, A + 1)).map(lambda t: f"{t[0]}\t{t[1]}\t"),
    st.sampled_from(["", "   ", "1", "1 2 3", "a\tb", "1.0\t2", "1e3\t0", "0x1\t0", "1_0\t0", "\x00\t0",
                     "99999999999999999999999\t0", "0,1", "nan\tnan"]),
    st.text(max_size=12),
)


@SETTINGS
@given(st.lists(line, max_size=12), st.sampled_from(["\n", "\r\n", "\r"]))
def test_random_text_trajectory(tmp_path, lines, eol):
    p = tmp_path / "traj_1.txt"
    p.write_text(eol.join(lines), encoding="utf-8", errors="surrogatepass")
    _check_text(p)


@SETTINGS
@given(st.binary(max_size=200))
def test_random_bytes_text_trajectory(tmp_path, data):
    p = tmp_path / "traj_1.txt"
    p.write_bytes(data)
    _check_text(p)


@SETTINGS
@given(hnp.arrays(st.sampled_from([np.float64, np.float32]),
                  hnp.array_shapes(min_dims=0, max_dims=4, max_side=4),
                  elements=st.floats(allow_nan=True, allow_infinity=True, width=32)))
def test_text_loader_with_bad_features(tmp_path, features):
    p = tmp_path / "traj_1.txt"
    p.write_text("0\t0\t\n1\t2\t\n")
    d = _check_text(p, features=features)
    if d is not None:
        assert d.features.shape[:2] == (S, A)


int_arrays = hnp.arrays(st.sampled_from([np.int64, np.int8, np.uint64, np.float64, np.bool_, np.float16]),
                        hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=6))
any_arrays = st.one_of(
    int_arrays,
    hnp.arrays(np.float64, hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=4)),
    hnp.arrays(hnp.unicode_string_dtypes(max_len=3), hnp.array_shapes(max_dims=2, max_side=3)),
    hnp.arrays(np.complex128, (2, 2, 1)),
)


def _valid_arrays():
    return {"features": FEATS, "states": np.array([0, 1, 2, 4, 3]), "actions": np.array([0, 2, 1, 1, 0]),
            "offsets": np.array([0, 2, 5]), "names": np.array(["a", "b"]),
            "feature_names": np.array(["f0", "f1"])}


@SETTINGS
@given(st.sampled_from(sorted(_valid_arrays())), any_arrays)
def test_npz_one_array_replaced(tmp_path, name, value):
    arrays = _valid_arrays()
    arrays[name] = value
    p = tmp_path / "demos.npz"
    np.savez(p, **arrays)
    _check_npz(p)


@SETTINGS
@given(st.dictionaries(st.sampled_from(["features", "states", "actions", "offsets", "names", "x"]),
                       any_arrays, max_size=6))
def test_npz_random_arrays(tmp_path, arrays):
    p = tmp_path / "demos.npz"
    np.savez(p, **arrays)
    _check_npz(p)


def _valid_npz_bytes() -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **_valid_arrays())
    return buf.getvalue()


@settings(SETTINGS, max_examples=60)
@given(st.data())
def test_npz_corrupted_bytes(tmp_path, data):
    raw = bytearray(_valid_npz_bytes())
    how = data.draw(st.sampled_from(["truncate", "flip", "random"]))
    if how == "truncate":
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    elif how == "flip":
        for _ in range(data.draw(st.integers(1, 8))):
            i = data.draw(st.integers(0, len(raw) - 1))
            raw[i] = data.draw(st.integers(0, 255))
    else:
        raw = bytearray(data.draw(st.binary(max_size=300)))
    p = tmp_path / "demos.npz"
    p.write_bytes(bytes(raw))
    _check_npz(p)


def test_npz_round_trip_and_specific_cases(tmp_path):
    d = load_npz(save_npz(load_npz(_write_npz(tmp_path / "ok.npz", _valid_arrays())), tmp_path / "again.npz"))
    assert d.n_trajectories == 2 and d.names == ("a", "b")
    with zipfile.ZipFile(tmp_path / "zip.npz", "w") as z:  # a zip holding no arrays
        z.writestr("readme.txt", "hello")
    with pytest.raises(DemonstrationError, match="zip.npz"):
        load_npz(tmp_path / "zip.npz")
    arrays = _valid_arrays()
    arrays["states"] = np.array([0, 1, 2, 4, 3], dtype=object)
    p = tmp_path / "obj.npz"
    np.savez(p, **arrays)
    with pytest.raises(DemonstrationError, match="obj.npz"):
        load_npz(p)


def test_npy_named_npz(tmp_path):
    np.save(tmp_path / "plain.npy", np.arange(3))  # a .npy, not an .npz
    (tmp_path / "plain.npz").write_bytes((tmp_path / "plain.npy").read_bytes())
    with pytest.raises(DemonstrationError, match="plain.npz"):
        load_npz(tmp_path / "plain.npz")


def test_npz_bad_crc(tmp_path):
    raw = bytearray(_valid_npz_bytes())
    i = raw.index(b"features.npy") + 200  # inside the first member's data
    raw[i] ^= 0xFF
    (tmp_path / "crc.npz").write_bytes(bytes(raw))
    with pytest.raises(DemonstrationError, match="crc.npz"):
        load_npz(tmp_path / "crc.npz")


def _write_npz(path, arrays):
    np.savez(path, **arrays)
    return path
