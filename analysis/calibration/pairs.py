"""Leader-follower pairs: loading the real NGSIM I-80 pairs and padding them into batches.

A pair file (``ngsim_i80_car_following/train/*.csv``) has the columns ``t, x_follower,
v_follower, a_follower, x_leader, v_leader, a_leader, leader_length, spacing, dv`` in feet,
ft/s, ft/s^2 at 0.1 s steps, with ``spacing = x_leader - x_follower - leader_length``. File
names carry the recording period, follower and leader ids:
``ngsim_<period>_run<period>_f<follower>_l<leader>_<n>.csv``.

Pairs are converted to SI (m, m/s) on load, the units of SUMO's car-following parameters.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from merge_irl.units import M_PER_FT
from scenarios.errors import SpecError

STEP_S = 0.1
_NAME = re.compile(r"^(?:ngsim_)?(?P<period>.+?)_run.*_f(?P<f>\d+)_l(?P<l>\d+)_(?P<n>\d+)$")
#: Fewest steps a pair (or a part of one, :func:`split_in_time`) may have.
MIN_STEPS = 10
_REQUIRED = ("t", "x_follower", "v_follower", "x_leader", "v_leader", "leader_length")
#: Shortest plausible leader (ft): below a motorcycle's 7 ft. A car given in metres is 3.5-5.5.
MIN_LEADER_LENGTH_FT = 7.0
#: A folder whose median leader is shorter than this (ft) is in metres (cars are about 15 ft).
MIN_MEDIAN_LEADER_LENGTH_FT = 9.0
#: Highest plausible speed (ft/s, about 100 mph), as for NGSIM trajectories.
MAX_SPEED_FT_S = 147.0
#: Highest plausible 99th percentile of the absolute acceleration (ft/s^2, about 1 g).
MAX_P99_ACC_FT_S2 = 33.0
#: Position advance over what the speeds imply, accepted as consistent (ratio of sums).
KINEMATIC_TOLERANCE = 0.07
#: Known unit mix-ups: position advance / distance the speeds imply -> likely cause.
_RATIO_CAUSES = ((0.3048, "positions in metres with speeds in ft/s"),
                 (1.0 / 0.3048, "speeds in m/s with positions in feet"),
                 (1.0 / 1.09728, "speeds in km/h with positions in feet"),
                 (1.0 / 0.681818, "speeds in mph with positions in feet"))
_CONVERT = "pair files are in ft, ft/s and ft/s^2 (NGSIM's units): convert the file (metres x 3.2808 = feet)"


@dataclass(frozen=True)
class CarFollowingPair:
    """One recorded leader-follower episode, SI units, uniform 0.1 s steps.

    Attributes:
        name: file stem.
        group: the follower's identity (``period/follower``); splits keep a group together.
        t: float64[T] time (s).
        x_follower, v_follower: float64[T] follower front position (m) and speed (m/s).
        x_leader, v_leader: float64[T] leader front position (m) and speed (m/s).
        leader_length: leader length (m).
    """

    name: str
    group: str
    t: np.ndarray
    x_follower: np.ndarray
    v_follower: np.ndarray
    x_leader: np.ndarray
    v_leader: np.ndarray
    leader_length: float

    @property
    def spacing(self) -> np.ndarray:
        """float64[T] bumper-to-bumper gap (m)."""
        return self.x_leader - self.leader_length - self.x_follower

    def __len__(self) -> int:
        return len(self.t)


def read_pair(path: str | Path) -> CarFollowingPair:
    """Read one pair CSV (feet) into a :class:`CarFollowingPair` (metres).

    Raises:
        SpecError: not a pair CSV (or empty), a missing column, fewer than :data:`MIN_STEPS` steps, steps
            that are not uniform 0.1 s, a value that is not a finite number, a negative speed, a
            bumper gap <= 0 (the leader not ahead of the follower) (file, column and line named),
            or values implausible in feet (:func:`check_pair_units`: the likely unit named).
    """
    path = Path(path)
    try:
        df = pd.read_csv(path)
    except pd.errors.EmptyDataError:
        raise SpecError(f"{path}: empty file; expected a pair CSV with the columns {list(_REQUIRED)}") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as e:
        raise SpecError(f"{path}: not a pair CSV: {e}") from e
    missing = [c for c in _REQUIRED if c not in df.columns]
    if missing:
        raise SpecError(f"{path}: missing column(s) {missing}; expected {list(_REQUIRED)}")
    if len(df) < MIN_STEPS:
        raise SpecError(f"{path}: {len(df)} rows; a pair needs at least {MIN_STEPS} steps")
    # text in a numeric column becomes NaN here and is refused below with its line
    arr = {c: pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=np.float64) for c in _REQUIRED}
    for c, v in arr.items():
        if not np.isfinite(v).all():
            i = int(np.argmax(~np.isfinite(v)))
            raise SpecError(f"{path}: column {c} line {i + 2}: {str(df[c].iloc[i])[:40]!r} is not a finite number")
    dt = np.diff(arr["t"])
    off = np.abs(dt - STEP_S) > 1e-6
    if off.any():
        i = int(np.argmax(off))  # the first step off, between lines i + 2 and i + 3
        raise SpecError(f"{path}: column t lines {i + 2}-{i + 3}: step {dt[i]:.6g} s; expected uniform {STEP_S} s steps")
    for c in ("v_follower", "v_leader"):
        if arr[c].min() < 0:
            i = int(np.argmin(arr[c]))
            raise SpecError(f"{path}: column {c} line {i + 2}: speed {arr[c][i]:g} < 0; speeds are forward, >= 0")
    check_pair_units(path, arr, {c: pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=np.float64)
                                 for c in ("a_follower", "a_leader") if c in df.columns})
    m = _NAME.match(path.stem)
    group = f"{m['period']}/{m['f']}" if m else path.stem
    pair = CarFollowingPair(
        name=path.stem, group=group, t=arr["t"],
        x_follower=arr["x_follower"] * M_PER_FT, v_follower=arr["v_follower"] * M_PER_FT,
        x_leader=arr["x_leader"] * M_PER_FT, v_leader=arr["v_leader"] * M_PER_FT,
        leader_length=float(arr["leader_length"][0]) * M_PER_FT,
    )
    gap = pair.spacing  # the gap the fits score
    if gap.min() <= 0:
        i = int(np.argmin(gap))
        raise SpecError(f"{path}: line {i + 2}: bumper gap x_leader - leader_length - x_follower = "
                        f"{gap[i] / M_PER_FT:g} ft <= 0: the leader is not ahead of the follower (columns swapped?)")
    return pair


def check_pair_units(path: Path, arr: dict[str, np.ndarray], acc: dict[str, np.ndarray]) -> None:
    """Check that one pair file's lengths, speeds and accelerations are plausible in feet, ft/s
    and ft/s^2 (the NGSIM reader checks trajectories the same way, :mod:`sim.ngsim.validate`).

    Args:
        arr: the file's :data:`_REQUIRED` columns, ``[T]`` each, as read (ft, ft/s).
        acc: its ``a_follower``/``a_leader`` columns when present (ft/s^2; NaN skipped).

    Raises:
        SpecError: one line naming the file, the column and the likely unit: a leader shorter than
            :data:`MIN_LEADER_LENGTH_FT` (metres), a speed above :data:`MAX_SPEED_FT_S` (km/h,
            mph), positions that advance by another distance than the speeds imply (mixed units),
            or accelerations whose 99th percentile exceeds :data:`MAX_P99_ACC_FT_S2`.
    """
    for c in ("v_follower", "v_leader"):
        if arr[c].max() > MAX_SPEED_FT_S:
            i = int(np.argmax(arr[c]))
            raise SpecError(f"{path}: column {c} line {i + 2}: speed {arr[c][i]:g}, above {MAX_SPEED_FT_S:g} ft/s "
                            f"(about 100 mph): km/h or mph?; {_CONVERT}")
    for x, v in (("x_follower", "v_follower"), ("x_leader", "v_leader")):
        implied = float(np.sum((arr[v][1:] + arr[v][:-1]) * (STEP_S / 2)))
        if implied > 50.0:
            ratio = float(arr[x][-1] - arr[x][0]) / implied
            if abs(ratio - 1.0) > KINEMATIC_TOLERANCE:
                cause = next((why for r, why in _RATIO_CAUSES if abs(ratio / r - 1.0) < KINEMATIC_TOLERANCE),
                             "positions and speeds in different units")
                raise SpecError(f"{path}: column {x}: advances {ratio:.3f} times the distance {v} implies (expected "
                                f"1 +- {KINEMATIC_TOLERANCE}): looks like {cause}; {_CONVERT}")
    length = float(arr["leader_length"][0])
    if length < MIN_LEADER_LENGTH_FT:
        raise SpecError(f"{path}: column leader_length: {length:g}, shorter than any vehicle in feet (cars are about "
                        f"15 ft, 4.5 m): the file looks like metres; {_CONVERT}")
    for c, a in acc.items():
        a = np.abs(a[np.isfinite(a)])
        if a.size and float(np.percentile(a, 99)) > MAX_P99_ACC_FT_S2:
            raise SpecError(f"{path}: column {c}: 99th percentile |acceleration| {float(np.percentile(a, 99)):.1f}, "
                            f"above {MAX_P99_ACC_FT_S2:g} ft/s^2 (about 1 g); {_CONVERT}")


def _check_folder_units(directory: str | Path, pairs: Sequence[CarFollowingPair]) -> None:
    """A folder whose median leader is shorter than :data:`MIN_MEDIAN_LEADER_LENGTH_FT` is in
    metres even where each file's trucks pass :func:`check_pair_units` (raises SpecError)."""
    if not pairs:
        return
    median_ft = float(np.median([p.leader_length for p in pairs])) / M_PER_FT
    if median_ft < MIN_MEDIAN_LEADER_LENGTH_FT:
        short = min(pairs, key=lambda p: p.leader_length)
        raise SpecError(f"{directory}: the median leader is {median_ft:.1f} long (e.g. {short.name}: "
                        f"{short.leader_length / M_PER_FT:g}); cars are about 15 ft: the files look like metres; "
                        f"{_CONVERT}")


def load_pairs(directory: str | Path, *, limit: int | None = None) -> tuple[CarFollowingPair, ...]:
    """All pairs under ``directory`` (``*.csv`` there, or in its ``train/`` subfolder), sorted by name.

    ``manifest.csv`` is skipped. ``limit`` keeps the first ``limit`` files (name order). Files that
    are byte-identical copies of another are kept (the result does not depend on it) but named in a
    :class:`DuplicatePairWarning`: the shared I-80 folder has 17 such copies of 302 files.

    Raises:
        FileNotFoundError: ``directory`` does not exist.
        SpecError: it holds no pair CSV files, a file is not a valid pair (see :func:`read_pair`),
            or the folder's leaders are too short to be in feet (metres).
    """
    files = pair_files(directory, limit=limit)
    copies = duplicate_files(files)
    if copies:
        shown = "; ".join(f"{c.name} = {o.name}" for c, o in copies[:3]) + ("; ..." if len(copies) > 3 else "")
        warnings.warn(
            f"{directory}: {len(copies)} of {len(files)} pair files are byte-identical copies of another "
            f"({shown}): each copy counts once more in the fits and held-out statistics; remove the copies "
            "to count every pair once", DuplicatePairWarning, stacklevel=2)
    pairs = tuple(read_pair(f) for f in files)
    _check_folder_units(directory, pairs)
    return pairs


class DuplicatePairWarning(UserWarning):
    """A pairs folder holds byte-identical files: the same pair would count more than once."""


def duplicate_files(files: Sequence[Path]) -> list[tuple[Path, Path]]:
    """``(copy, original)`` for every file whose bytes equal an earlier file's (in the order given).

    Raises:
        OSError: a file cannot be read.
    """
    seen: dict[bytes, Path] = {}
    out = []
    for f in files:
        digest = hashlib.blake2b(Path(f).read_bytes(), digest_size=16).digest()
        if digest in seen:
            out.append((Path(f), seen[digest]))
        else:
            seen[digest] = Path(f)
    return out


def pair_files(directory: str | Path, *, limit: int | None = None) -> list[Path]:
    """The pair CSV files :func:`load_pairs` reads, in the same order.

    Raises:
        FileNotFoundError: ``directory`` does not exist.
        SpecError: it is a file, or holds no pair CSV.
    """
    d = Path(directory)
    if d.is_file():
        raise SpecError(f"{d}: a file; expected a folder of pair CSVs (*.csv, or train/*.csv below it)")
    if not d.is_dir():
        raise FileNotFoundError(f"pairs directory not found: {d}")
    files = sorted(p for p in d.glob("*.csv") if p.name != "manifest.csv")
    if not files and (d / "train").is_dir():
        files = sorted(p for p in (d / "train").glob("*.csv") if p.name != "manifest.csv")
    if not files:
        raise SpecError(f"{d}: no pair CSV files found (expected *.csv or train/*.csv)")
    if limit is not None:
        files = files[:limit]
    return files


def split_by_follower(
    pairs: Sequence[CarFollowingPair], test_fraction: float, seed: int
) -> tuple[tuple[CarFollowingPair, ...], tuple[CarFollowingPair, ...]]:
    """(train, test): followers (groups) drawn at random for test, never in both; at least one
    follower on each side.

    Raises:
        SpecError: ``test_fraction`` not in (0, 1), or fewer than 2 followers to split.
    """
    if isinstance(test_fraction, bool) or not isinstance(test_fraction, (int, float)) or not 0 < test_fraction < 1:
        raise SpecError(f"held-out fraction: expected a number in (0, 1), got {test_fraction!r}")
    groups = sorted({p.group for p in pairs})
    rng = np.random.default_rng(seed)
    if len(groups) < 2:
        raise SpecError(f"held-out fraction: {len(groups)} follower(s) cannot be split into training and held-out")
    n_test = min(len(groups) - 1, max(1, int(round(test_fraction * len(groups)))))
    test_groups = set(rng.choice(groups, size=n_test, replace=False).tolist())
    train = tuple(p for p in pairs if p.group not in test_groups)
    test = tuple(p for p in pairs if p.group in test_groups)
    return train, test


def split_in_time(pair: CarFollowingPair, fraction: float) -> tuple[CarFollowingPair, CarFollowingPair]:
    """(first part, rest) of one pair, cut after ``round(fraction * T)`` of its T steps.

    The rest starts at the first part's last step, so a follower simulated over the rest starts
    from the recorded state where the first part ends (the within-driver validation of
    calibration practice: fit a driver on the first part of a trajectory, score it on the rest;
    Punzo, Montanino & Ciuffo, *Transp. Res. Rec.* 2012). Both parts keep the pair's name and
    group.

    Raises:
        SpecError: ``fraction`` not in (0, 1), or a part shorter than :data:`MIN_STEPS` steps.
    """
    if isinstance(fraction, bool) or not isinstance(fraction, (int, float)) or not 0.0 < fraction < 1.0:
        raise SpecError(f"fraction: expected a number in (0, 1), got {fraction!r}")
    n = len(pair)
    cut = int(round(fraction * n))
    if cut < MIN_STEPS or n - cut + 1 < MIN_STEPS:
        raise SpecError(f"{pair.name}: cutting {n} steps at {fraction} leaves {cut} and {n - cut + 1} steps; "
                        f"each part needs at least {MIN_STEPS}")

    def part(a: int, b: int) -> CarFollowingPair:
        return replace(pair, t=pair.t[a:b], x_follower=pair.x_follower[a:b], v_follower=pair.v_follower[a:b],
                       x_leader=pair.x_leader[a:b], v_leader=pair.v_leader[a:b])

    return part(0, cut), part(cut - 1, n)


@dataclass(frozen=True)
class PairBatch:
    """Pairs padded to a common length T, rows sorted by decreasing length.

    Row ``i`` holds ``pairs[order[i]]``; :meth:`unsort` maps per-row results back to the
    order of the pairs given. Past a pair's end its leader keeps its last speed.

    Attributes:
        x_leader, v_leader: float64[P, T]; spacing_obs: float64[P, T] observed gap (m).
        x0, v0: float64[P] follower's initial position and speed; leader_length: float64[P].
        mask: bool[P, T], True on the steps scored (1 .. len-1 of each pair).
        lengths: int64[P], decreasing.
        order: int64[P], row -> index of the pair in the sequence given.
    """

    x_leader: np.ndarray
    v_leader: np.ndarray
    spacing_obs: np.ndarray
    x0: np.ndarray
    v0: np.ndarray
    leader_length: np.ndarray
    mask: np.ndarray
    lengths: np.ndarray
    order: np.ndarray

    def unsort(self, values: np.ndarray) -> np.ndarray:
        """Per-row values (first axis P) back in the order of the pairs given."""
        out = np.empty_like(values)
        out[self.order] = values
        return out

    @classmethod
    def from_pairs(cls, pairs: Sequence[CarFollowingPair]) -> PairBatch:
        """The pairs as ``[P, T]`` arrays, longest first (leaders extended at constant speed), with the mask of
        scored steps.

        Raises:
            SpecError: ``pairs`` is empty.
        """
        if not pairs:
            raise SpecError("no pairs given")
        order = np.argsort([-len(p) for p in pairs], kind="stable")
        pairs = [pairs[i] for i in order]
        T = max(len(p) for p in pairs)
        P = len(pairs)
        xl, vl, so = np.empty((P, T)), np.empty((P, T)), np.zeros((P, T))
        mask = np.zeros((P, T), dtype=bool)
        for i, p in enumerate(pairs):
            n = len(p)
            xl[i, :n], vl[i, :n] = p.x_leader, p.v_leader
            xl[i, n:] = p.x_leader[-1] + p.v_leader[-1] * STEP_S * np.arange(1, T - n + 1)
            vl[i, n:] = p.v_leader[-1]
            so[i, :n] = p.spacing
            mask[i, 1:n] = True
        return cls(
            x_leader=xl, v_leader=vl, spacing_obs=so,
            x0=np.array([p.x_follower[0] for p in pairs]),
            v0=np.array([p.v_follower[0] for p in pairs]),
            leader_length=np.array([p.leader_length for p in pairs]),
            mask=mask, lengths=np.array([len(p) for p in pairs], dtype=np.int64),
            order=order.astype(np.int64),
        )


def load_split(path: str | Path, test_fraction: float, seed: int, *, quiet_duplicates: bool = True
               ) -> tuple[tuple[CarFollowingPair, ...], tuple[CarFollowingPair, ...], tuple[CarFollowingPair, ...]]:
    """``(pairs, train, test)``: every pair in ``path`` (:func:`load_pairs`, in its order) and
    their :func:`split_by_follower`
    (the split of ``calibrate fit --holdout`` and ``learn-driver --holdout`` at the same fraction
    and seed). ``quiet_duplicates``: no :class:`DuplicatePairWarning` (a report that names the
    copies elsewhere); every other warning is shown.

    Raises:
        as :func:`load_pairs` and :func:`split_by_follower`.
    """
    with warnings.catch_warnings():
        if quiet_duplicates:
            warnings.simplefilter("ignore", DuplicatePairWarning)
        pairs = tuple(load_pairs(path))
    return (pairs, *split_by_follower(pairs, test_fraction, seed))
