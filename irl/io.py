"""Reading and writing tabular demonstrations.

Two formats:

* the authors' text format (RAILUSM/Model-free-IRL ``data/``): one file per trajectory, one
  step per line, ``state<TAB>action<TAB>`` (any whitespace separates the two integers; blank
  lines are ignored). A directory is read in natural file-name order (``traj_2`` before
  ``traj_10``). The files carry no features: the caller passes ``features [S, A, K]``.
* a generic ``.npz`` with arrays ``features [S, A, K]`` (float), ``states [N]``, ``actions [N]``
  (integers; all trajectories concatenated), ``offsets [n_traj + 1]`` (trajectory ``i`` is
  ``states[offsets[i]:offsets[i+1]]``) and optionally ``feature_names [K]`` (strings) and
  ``names [n_traj]`` (trajectory names).

Every malformed input raises :class:`irl.errors.DemonstrationError` naming the file (and the
line or array) at fault and what was expected.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationInfo, field_validator, model_validator

from irl.demonstrations import Demonstrations
from irl.errors import DemonstrationError
from merge_irl.atomic import write_atomic, write_text_atomic
from merge_irl.json_file import validate
from merge_irl.tables import PARQUET_SUFFIXES

_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple:
    """Sort key putting ``traj_2`` before ``traj_10``."""
    return tuple(int(p) if p.isdigit() else p for p in _DIGITS.split(name))


def trajectory_files(path: str | os.PathLike) -> list[Path]:
    """The trajectory files a text-format path stands for, in natural order.

    A file stands for itself; a directory for its ``*.txt`` files.

    Raises:
        DemonstrationError: ``path`` does not exist, or is a folder without ``*.txt`` files.
    """
    path = Path(path)
    if not path.exists():
        raise DemonstrationError(f"{path}: no such file or directory")
    if path.is_file():
        return [path]
    files = sorted((p for p in path.iterdir() if p.is_file() and p.suffix == ".txt"),
                   key=lambda p: natural_key(p.name))
    if not files:
        tables = any(p.suffix.lower() in PARQUET_SUFFIXES for p in path.rglob("*"))
        raise DemonstrationError(
            f"{path}: directory holds no trajectory files (*.txt)"
            + ("; its Parquet files are not the part files of one table (they differ in columns or are unreadable)"
               if tables else ""))
    return files


def _parse_int(token: str, what: str, where: str, limit: int) -> int:
    try:
        value = int(token)
    except ValueError:
        raise DemonstrationError(f"{where}: {what} {token!r} is not an integer") from None
    if not 0 <= value < limit:
        raise DemonstrationError(f"{where}: {what} {value} out of range [0, {limit})")
    return value


def read_text_trajectory(path: Path, n_states: int, n_actions: int) -> tuple[np.ndarray, np.ndarray]:
    """One text-format trajectory: ``states [T]``, ``actions [T]`` (int64).

    Raises:
        DemonstrationError: the file is empty, not text, or has a line that is not ``state<TAB>action``
            integers (file and line named).
    """
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise DemonstrationError(f"{path}: not a text file") from None
    states: list[int] = []
    actions: list[int] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        tokens = line.split()
        if not tokens:
            continue
        where = f"{path}:{lineno}"
        if len(tokens) != 2:
            raise DemonstrationError(
                f"{where}: expected 2 columns 'state<TAB>action', got {len(tokens)}: {line.strip()!r}"
            )
        states.append(_parse_int(tokens[0], "state", where, n_states))
        actions.append(_parse_int(tokens[1], "action", where, n_actions))
    if not states:
        raise DemonstrationError(f"{path}: empty trajectory file (no 'state<TAB>action' lines)")
    return np.asarray(states, dtype=np.int64), np.asarray(actions, dtype=np.int64)


def load_text_trajectories(
    path_or_dir: str | os.PathLike, *, n_states: int, n_actions: int, features: np.ndarray
) -> Demonstrations:
    """Load the authors' text format.

    Args:
        path_or_dir: one trajectory file, or a directory of ``*.txt`` trajectory files.
        n_states, n_actions: ``S``, ``A``; states/actions outside ``[0, S)``/``[0, A)`` are errors.
        features: ``[S, A, K]`` reward features.

    Returns:
        Demonstrations with one trajectory per file, named by file name.

    Raises:
        DemonstrationError: a missing or empty file/directory, a malformed line, a state or
            action out of range, or features of the wrong shape (naming the file and line).
    """
    features = np.asarray(features, dtype=np.float64)
    if features.ndim != 3 or features.shape[:2] != (n_states, n_actions):
        raise DemonstrationError(
            f"{path_or_dir}: features must have shape [S={n_states}, A={n_actions}, K], got {features.shape}"
        )
    files = trajectory_files(path_or_dir)
    pairs = [read_text_trajectory(f, n_states, n_actions) for f in files]
    return Demonstrations(
        states=tuple(p[0] for p in pairs),
        actions=tuple(p[1] for p in pairs),
        features=features,
        n_states=n_states,
        n_actions=n_actions,
        source=str(path_or_dir),
        names=tuple(f.name for f in files),
    )


def save_text_trajectories(demos: Demonstrations, directory: str | os.PathLike, prefix: str = "traj_") -> list[Path]:
    """Write one ``state<TAB>action<TAB>`` file per trajectory (``prefix{i}.txt``)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out = []
    for i, (s, a) in enumerate(zip(demos.states, demos.actions)):
        text = "".join(f"{int(x)}\t{int(y)}\t\n" for x, y in zip(s, a))
        out.append(write_text_atomic(directory / f"{prefix}{i}.txt", text))
    return out


_REQUIRED = ("features", "states", "actions", "offsets")


def _int_array(arr: np.ndarray) -> np.ndarray:
    """``arr`` as a 1-D int64 array (integral floats allowed); ValueError naming the entry at fault."""
    if arr.ndim != 1:
        raise ValueError(f"must be 1-D, got shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.integer):
        if arr.dtype == np.uint64 and arr.size and int(arr.max()) > 2**62:
            j = int(np.argmax(arr))
            raise ValueError(f"entry {j} = {arr[j]} is out of range")
        return arr.astype(np.int64)
    if np.issubdtype(arr.dtype, np.floating):
        with np.errstate(invalid="ignore", over="ignore"):  # float16: 2**62 casts to inf
            bad = np.flatnonzero(~np.isfinite(arr) | (arr != np.round(arr)) | (np.abs(arr) > 2.0**62))
        if bad.size:
            raise ValueError(f"entry {bad[0]} = {arr[bad[0]]} is not an integer")
        return arr.astype(np.int64)
    raise ValueError(f"must hold integers, got dtype {arr.dtype}")


class NpzManifest(BaseModel):
    """The schema of a demonstrations ``.npz``: its arrays (the module docstring), each checked in
    itself and against the ones before it; the states' and actions' range last."""

    model_config = ConfigDict(arbitrary_types_allowed=True, extra="ignore")

    features: np.ndarray
    states: np.ndarray
    actions: np.ndarray
    offsets: np.ndarray
    names: np.ndarray | None = None
    feature_names: np.ndarray | None = None

    @field_validator("features")
    @classmethod
    def _features(cls, f: np.ndarray) -> np.ndarray:
        if f.ndim != 3 or 0 in f.shape:
            raise ValueError(f"must have shape [S, A, K], got {f.shape}")
        if not np.issubdtype(f.dtype, np.number) or np.issubdtype(f.dtype, np.complexfloating):
            raise ValueError(f"must be real numbers, got dtype {f.dtype}")
        f = f.astype(np.float64)
        bad = np.argwhere(~np.isfinite(f))
        if bad.size:
            s, a, k = bad[0]
            raise ValueError(f"entry [{s}, {a}, {k}] is {f[s, a, k]}")
        return f

    @field_validator("states")
    @classmethod
    def _states(cls, arr: np.ndarray) -> np.ndarray:
        return _int_array(arr)

    @field_validator("actions")
    @classmethod
    def _actions(cls, arr: np.ndarray, info: ValidationInfo) -> np.ndarray:
        arr = _int_array(arr)
        states = info.data.get("states")
        if states is not None and states.shape != arr.shape:
            raise ValueError(f"{arr.shape} and 'states' {states.shape} differ in length")
        return arr

    @field_validator("offsets")
    @classmethod
    def _offsets(cls, arr: np.ndarray, info: ValidationInfo) -> np.ndarray:
        offsets = _int_array(arr)
        if offsets.size < 2:
            raise ValueError("needs at least 2 entries [0, ..., N]")
        n = info.data["states"].size if "states" in info.data else offsets[-1]
        if offsets[0] != 0 or offsets[-1] != n:
            raise ValueError(f"must start at 0 and end at N = {n}, got {offsets[0]} ... {offsets[-1]}")
        steps = np.diff(offsets)
        if np.any(steps < 0):
            raise ValueError(f"not monotone at entry {int(np.flatnonzero(steps < 0)[0]) + 1}")
        if np.any(steps == 0):
            i = int(np.flatnonzero(steps == 0)[0])
            raise ValueError(f"trajectory {i} is empty (offsets[{i}] == offsets[{i + 1}])")
        return offsets

    @field_validator("names")
    @classmethod
    def _names(cls, raw: np.ndarray | None, info: ValidationInfo) -> np.ndarray | None:
        n = info.data["offsets"].size - 1 if "offsets" in info.data else None
        if raw is not None and (raw.ndim != 1 or (n is not None and raw.size != n)):
            raise ValueError(f"must hold {n} trajectory names, got shape {raw.shape}")
        return raw

    @field_validator("feature_names")
    @classmethod
    def _feature_names(cls, fn: np.ndarray | None, info: ValidationInfo) -> np.ndarray | None:
        k = info.data["features"].shape[2] if "features" in info.data else None
        if fn is not None and (fn.ndim != 1 or (k is not None and fn.size != k)):
            raise ValueError(f"must hold K = {k} names, got shape {fn.shape}")
        return fn

    @model_validator(mode="after")
    def _in_range(self) -> NpzManifest:
        n_states, n_actions, _ = self.features.shape
        for arr, kind, n in ((self.states, "state", n_states), (self.actions, "action", n_actions)):
            bad_i = np.flatnonzero((arr < 0) | (arr >= n))
            if bad_i.size:
                j = int(bad_i[0])
                traj = int(np.searchsorted(self.offsets, j, side="right") - 1)
                raise ValueError(f"array '{kind}s' entry {j} (trajectory {traj}, step {j - self.offsets[traj]}): "
                                 f"{kind} {arr[j]} out of range [0, {n})")
        return self


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` at ``path``.

    Raises:
        DemonstrationError: a missing or unreadable file, or a single ``.npy``.
    """
    if not path.is_file():
        raise DemonstrationError(f"{path}: no such file")
    try:
        loaded = np.load(path, allow_pickle=False)
    except Exception as e:  # numpy/zipfile raise many types for a corrupt file
        raise DemonstrationError(f"{path}: not a readable .npz file ({type(e).__name__}: {e})") from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise DemonstrationError(f"{path}: holds a single .npy array, expected an .npz archive of named arrays")
    try:
        with loaded as data:
            return {k: data[k] for k in data.files}
    except Exception as e:  # corrupt members: bad CRC, truncated data, unsupported compression
        raise DemonstrationError(f"{path}: not a readable .npz file ({type(e).__name__}: {e})") from None


def load_npz(path: str | os.PathLike) -> Demonstrations:
    """Load the generic ``.npz`` format (see the module docstring), its arrays checked by
    :class:`NpzManifest`.

    Raises:
        DemonstrationError: a missing or unreadable file, a missing array, or an array of the
            wrong dtype, shape or range (one line naming the file, the array and the entry).
    """
    path = Path(path)
    where = str(path)
    arrays = _read_arrays(path)
    missing = [k for k in _REQUIRED if k not in arrays]
    if missing:
        raise DemonstrationError(f"{where}: missing array(s) {missing}; expected {list(_REQUIRED)}")
    m = validate(NpzManifest, arrays, where, error=DemonstrationError)
    cut = [slice(m.offsets[i], m.offsets[i + 1]) for i in range(m.offsets.size - 1)]
    n_states, n_actions, _ = m.features.shape
    return Demonstrations(
        states=tuple(m.states[c] for c in cut), actions=tuple(m.actions[c] for c in cut), features=m.features,
        n_states=n_states, n_actions=n_actions, source=where,
        names=() if m.names is None else tuple(str(x) for x in m.names),
    )


def load_feature_names(path: str | os.PathLike) -> tuple[str, ...]:
    """The optional ``feature_names`` array of a ``.npz`` demonstrations file (empty if absent)."""
    with np.load(Path(path), allow_pickle=False) as data:
        if "feature_names" not in data.files:
            return ()
        return tuple(str(x) for x in data["feature_names"])


def save_npz(demos: Demonstrations, path: str | os.PathLike, feature_names: tuple[str, ...] = ()) -> Path:
    """Write ``demos`` in the generic ``.npz`` format, atomically.

    Raises:
        DemonstrationError: the number of feature names is not the number of features.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    states, actions, offsets = demos.flat()
    arrays = {"features": np.asarray(demos.features), "states": states, "actions": actions,
              "offsets": offsets}
    if feature_names:
        if len(feature_names) != demos.n_features:
            raise DemonstrationError(
                f"{path}: {len(feature_names)} feature names for K = {demos.n_features} features"
            )
        arrays["feature_names"] = np.asarray(feature_names, dtype=str)
    if demos.names:
        arrays["names"] = np.asarray(demos.names, dtype=str)
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file object: np.savez would add ".npz" to a path
            np.savez(f, **arrays)  # type: ignore[arg-type]  # numpy stub: a ** dict might hold allow_pickle

    return write_atomic(path, write)
