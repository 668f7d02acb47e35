"""A learned driver on real car-following pairs, beside SUMO's defaults and a calibration.

Each pair's recorded leader is replayed; the learned driver follows from the recorded initial
state, taking its most likely action every decision (deterministic; the driver's format says how:
:func:`sim.drivers.formats.replay_act`), integrated exactly at
0.1 s (:func:`irl.planning.replay.replay`). Scored per pair: the spacing RMSE
(bumper gap, m) and a collision (bumper gap <= 0). Beside it on the same pairs: IDM with SUMO's
default parameters (:data:`analysis.calibration.models.SUMO_DEFAULTS`, the numpy replica) and,
when given, a calibration of ``merge-irl calibrate fit`` (its model, population or driver
classes). Every statistic weighs the pairs equally, with a bootstrap interval over pairs.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.calibration.evaluate import Interval, bootstrap_intervals, evaluate, paired_statistics
from analysis.calibration.models import SUMO_DEFAULTS
from analysis.calibration.objective import spacing_rmse
from analysis.calibration.pairs import CarFollowingPair, PairBatch
from analysis.calibration.result import CalibrationResult
from irl.planning.replay import ActFn, ReplayPair, replay
from merge_irl.units import FT_PER_M
from scenarios.errors import SpecError
from sim.drivers.formats import replay_act


@dataclass(frozen=True)
class DriverEvaluation:
    """A driver's spacing RMSE (m) and collisions on pairs, beside SUMO's defaults and a calibration.

    Attributes:
        driver: the driver file; n_pairs: pairs scored; names: ``[P]`` their names.
        rmse_m, default_rmse_m: ``[P]`` per pair, the driver's and IDM with SUMO's defaults.
        calibrated_rmse_m: ``[P]`` the calibration's, or None.
        collided: ``[P]`` bool, the driver's bumper gap reached 0.
        min_gap_m: ``[P]`` the driver's smallest bumper gap (m).
        intervals: ``(statistic, Interval)`` of the medians, means and ratios (95 % bootstrap).
    """

    driver: str
    names: tuple[str, ...]
    rmse_m: np.ndarray
    default_rmse_m: np.ndarray
    calibrated_rmse_m: np.ndarray | None
    collided: np.ndarray
    min_gap_m: np.ndarray
    intervals: tuple[tuple[str, Interval], ...]

    @property
    def n_pairs(self) -> int:
        return len(self.names)

    def to_json_dict(self) -> dict[str, Any]:
        """The summary as ``calibrate evaluate --driver --json`` prints it."""
        out: dict[str, Any] = {
            "driver": self.driver, "n_pairs": self.n_pairs,
            "median_rmse_m": float(np.median(self.rmse_m)), "mean_rmse_m": float(np.mean(self.rmse_m)),
            "default_median_rmse_m": float(np.median(self.default_rmse_m)),
            "default_mean_rmse_m": float(np.mean(self.default_rmse_m)),
            "collisions": int(self.collided.sum()),
        }
        if self.calibrated_rmse_m is not None:
            out["calibrated_median_rmse_m"] = float(np.median(self.calibrated_rmse_m))
            out["calibrated_mean_rmse_m"] = float(np.mean(self.calibrated_rmse_m))
        out["intervals"] = {k: [iv.value, iv.low, iv.high] for k, iv in self.intervals}
        return out


def replay_pairs(pairs: Sequence[CarFollowingPair]) -> list[ReplayPair]:
    """The pairs in the replay's units (ft, ft/s)."""
    return [ReplayPair(p.name, p.x_follower * FT_PER_M, p.v_follower * FT_PER_M, p.x_leader * FT_PER_M,
                       p.v_leader * FT_PER_M, p.leader_length * FT_PER_M) for p in pairs]


def evaluate_driver(path: str | os.PathLike, pairs: Sequence[CarFollowingPair], *,
                    calibration: CalibrationResult | None = None, seed: int = 0) -> DriverEvaluation:
    """Replay ``pairs`` with the driver of ``path`` and score it beside SUMO's IDM defaults and
    ``calibration`` (module docstring); ``seed`` seeds the bootstrap.

    Raises:
        SpecError: no pairs.
        ModelFileError: a bad driver file.
    """
    if not pairs:
        raise SpecError("evaluate --driver: no pairs to score")
    act, step = replay_act(path)
    return evaluate_act(act, step, pairs, calibration=calibration, seed=seed, driver=str(Path(path)))


def evaluate_act(act: ActFn, decision_step_s: float, pairs: Sequence[CarFollowingPair], *,
                 calibration: CalibrationResult | None = None, seed: int = 0, driver: str = "") -> DriverEvaluation:
    """:func:`evaluate_driver` of a driver given as its replay action ``act`` (ft/s^2 of ``obs
    [N, 7]``, ``prev_acc [N]``, ``acc_C [N]``) deciding every ``decision_step_s``, named ``driver``.

    Raises:
        SpecError: no pairs.
    """
    if not pairs:
        raise SpecError("evaluate --driver: no pairs to score")
    res = replay(replay_pairs(pairs), act, decision_step_s)
    batch = PairBatch.from_pairs(pairs)
    d = batch.unsort(spacing_rmse("idm", batch, SUMO_DEFAULTS.as_dict()))
    cal = None
    if calibration is not None:
        ev = evaluate(calibration.population, pairs, model=calibration.model, classes=calibration.classes)
        cal = np.array([s.rmse_m for s in ev.pairs])
    r = np.asarray(res.rmse_m, dtype=np.float64)
    stats = paired_statistics(r, d, win_fraction=False)
    if cal is not None:
        stats["calibrated_median_rmse_m"] = (np.median, (cal,))
        stats["calibrated_mean_rmse_m"] = (np.mean, (cal,))
    intervals = bootstrap_intervals(stats, seed)
    return DriverEvaluation(driver, tuple(p.name for p in pairs), r, d, cal,
                            np.asarray(res.collided, dtype=bool), np.asarray(res.min_gap_m, dtype=np.float64), intervals)
