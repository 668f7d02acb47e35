"""Loaders of tabular demonstrations: the authors' text format and the generic .npz."""

from pathlib import Path

import numpy as np
import pytest

from irl.demonstrations import Demonstrations
from irl.errors import DemonstrationError
from irl.io import load_npz, load_text_trajectories, natural_key, save_npz, save_text_trajectories

S, A, K = 6, 3, 2


def feats(s=S, a=A, k=K):
    return np.arange(s * a * k, dtype=float).reshape(s, a, k) / 10.0


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_text_directory_loads_in_natural_order(tmp_path):
    for i, text in [(10, "5\t2\t\n"), (2, "1\t0\t\n2\t1\t\n"), (1, "0\t0\t\n")]:
        write(tmp_path / f"traj_{i}.txt", text)
    write(tmp_path / "notes.md", "ignored")
    d = load_text_trajectories(tmp_path, n_states=S, n_actions=A, features=feats())
    assert d.names == ("traj_1.txt", "traj_2.txt", "traj_10.txt")
    assert [list(s) for s in d.states] == [[0], [1, 2], [5]]
    assert [list(a) for a in d.actions] == [[0], [0, 1], [2]]
    assert natural_key("traj_10") > natural_key("traj_9")


def test_text_round_trip(tmp_path):
    d = load_text_trajectories(write(tmp_path / "a" / "t.txt", "1 2\n3 0\n\n"), n_states=S, n_actions=A, features=feats())
    save_text_trajectories(d, tmp_path / "out")
    back = load_text_trajectories(tmp_path / "out", n_states=S, n_actions=A, features=feats())
    assert [list(s) for s in back.states] == [[1, 3]]
    assert [list(a) for a in back.actions] == [[2, 0]]


@pytest.mark.parametrize(
    "text, message",
    [
        ("1\t0\t\nx\t1\t\n", r"t\.txt:2: state 'x' is not an integer"),
        ("1\t0.5\t\n", r"t\.txt:1: action '0\.5' is not an integer"),
        ("1\t0\t2\t\n", r"t\.txt:1: expected 2 columns"),
        ("1\n", r"t\.txt:1: expected 2 columns"),
        ("1\t0\t\n6\t0\t\n", r"t\.txt:2: state 6 out of range \[0, 6\)"),
        ("1\t3\t\n", r"t\.txt:1: action 3 out of range \[0, 3\)"),
        ("-1\t0\t\n", r"t\.txt:1: state -1 out of range"),
        ("", r"t\.txt: empty trajectory file"),
        ("\n  \n", r"t\.txt: empty trajectory file"),
    ],
)
def test_text_rejects_bad_files(tmp_path, text, message):
    path = write(tmp_path / "t.txt", text)
    with pytest.raises(DemonstrationError, match=message):
        load_text_trajectories(path, n_states=S, n_actions=A, features=feats())


def test_text_rejects_empty_dir_missing_path_and_bad_features(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(DemonstrationError, match=r"empty: directory holds no trajectory files"):
        load_text_trajectories(tmp_path / "empty", n_states=S, n_actions=A, features=feats())
    with pytest.raises(DemonstrationError, match=r"nope: no such file or directory"):
        load_text_trajectories(tmp_path / "nope", n_states=S, n_actions=A, features=feats())
    path = write(tmp_path / "t.txt", "1\t0\t\n")
    with pytest.raises(DemonstrationError, match=r"features must have shape \[S=6, A=3, K\]"):
        load_text_trajectories(path, n_states=S, n_actions=A, features=np.zeros((S, A + 1, K)))
    bad = feats()
    bad[2, 1, 0] = np.nan
    with pytest.raises(DemonstrationError, match=r"feature \[2, 1, 0\] is not finite in .*t\.txt"):
        load_text_trajectories(path, n_states=S, n_actions=A, features=bad)


def make_npz(path, **over):
    arrays = {"features": feats(), "states": np.array([0, 1, 2, 5]), "actions": np.array([0, 1, 2, 0]),
              "offsets": np.array([0, 3, 4])}
    arrays.update(over)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    np.savez(path, **arrays)
    return path


def test_npz_round_trip(tmp_path):
    d = Demonstrations((np.array([0, 1, 2]), np.array([5])), (np.array([0, 1, 2]), np.array([0])), feats(), S, A,
                       names=("a", "b"))
    p = save_npz(d, tmp_path / "sub" / "d.npz", feature_names=("speed", "safe"))
    back = load_npz(p)
    assert back.names == ("a", "b")
    assert [list(s) for s in back.states] == [[0, 1, 2], [5]]
    np.testing.assert_array_equal(back.features, d.features)
    from irl.io import load_feature_names

    assert load_feature_names(p) == ("speed", "safe")
    assert not list((tmp_path / "sub").glob("*.tmp"))


@pytest.mark.parametrize(
    "over, message",
    [
        ({"offsets": None}, r"missing array\(s\) \['offsets'\]"),
        ({"features": np.zeros((S, A))}, r"features: must have shape \[S, A, K\], got \(6, 3\)"),
        ({"features": np.full((S, A, K), np.nan)}, r"features: entry \[0, 0, 0\] is nan"),
        ({"states": np.array([0, 1, 2])}, r"actions: \(4,\) and 'states' \(3,\) differ in length"),
        ({"states": np.array([0.0, 1.5, 2, 5])}, r"states: entry 1 = 1.5 is not an integer"),
        ({"states": np.array(["a", "b", "c", "d"])}, r"states: must hold integers, got dtype <U1"),
        ({"offsets": np.array([0, 3, 5])}, r"offsets: must start at 0 and end at N = 4"),
        ({"offsets": np.array([0, 3, 2, 4])}, r"offsets: not monotone at entry 2"),
        ({"offsets": np.array([0, 0, 4])}, r"offsets: trajectory 0 is empty"),
        ({"states": np.array([0, 1, 9, 5])}, r"'states' entry 2 \(trajectory 0, step 2\): state 9 out of range \[0, 6\)"),
        ({"actions": np.array([0, 1, 2, 3])}, r"'actions' entry 3 \(trajectory 1, step 0\): action 3 out of range"),
        ({"feature_names": np.array(["x"])}, r"feature_names: must hold K = 2 names"),
    ],
)
def test_npz_rejects_bad_files(tmp_path, over, message):
    path = make_npz(tmp_path / "bad.npz", **over)
    with pytest.raises(DemonstrationError, match=r"bad\.npz: (array )?(arrays )?" + message):
        load_npz(path)


def test_npz_rejects_non_npz(tmp_path):
    path = write(tmp_path / "x.npz", "not a zip")
    with pytest.raises(DemonstrationError, match=r"x\.npz: not a readable \.npz file"):
        load_npz(path)
    with pytest.raises(DemonstrationError, match=r"missing\.npz: no such file"):
        load_npz(tmp_path / "missing.npz")


def test_authors_gridworld_files_load(railusm):
    from irl.domains import gridworld

    d = gridworld.load(railusm / "gridworld" / "noise_0.0_expert_trajs")
    assert d.n_trajectories == 12 and d.n_steps == 33
    d = gridworld.load(railusm / "gridworld" / "noise_0.1_expert_trajs")
    assert d.n_trajectories == 14 and d.n_steps == 52


def test_npz_rejects_npy_and_corrupt_archives(tmp_path):
    npy = tmp_path / "arr.npz"
    with open(npy, "wb") as f:
        np.save(f, np.arange(3))
    with pytest.raises(DemonstrationError, match=r"arr\.npz: holds a single \.npy array"):
        load_npz(npy)
    good = make_npz(tmp_path / "good.npz")
    raw = bytearray(good.read_bytes())
    raw[len(raw) // 2: len(raw) // 2 + 40] = bytes(40)  # zero a stretch of array data: CRC mismatch
    bad = tmp_path / "crc.npz"
    bad.write_bytes(bytes(raw))
    with pytest.raises(DemonstrationError, match=r"crc\.npz: not a readable \.npz file"):
        load_npz(bad)
    huge = make_npz(tmp_path / "huge.npz", states=np.array([0.0, 1.0, 1e300, 5.0]))
    with pytest.raises(DemonstrationError, match=r"huge\.npz: states: entry 2 = 1e\+300 is not an integer"):
        load_npz(huge)
