"""Car-following calibration against real NGSIM I-80 leader-follower pairs.

Replay the recorded leader, simulate the follower with a numpy replica of SUMO 1.28's
car-following update (IDM, or Krauss with sigma = 0), and fit the parameters that minimise the
spacing error (``scipy.optimize.least_squares``): a population fit plus per-pair fits, whose
spread describes how drivers differ. EIDM, which has no replica, is fitted and evaluated through
real SUMO runs (:mod:`.sumo_fit`, population fit only). The calibrated population feeds the
``i80`` scenario's vType distribution.

Modules: :mod:`.pairs` (loading, batches, split by follower), :mod:`.models` (the SUMO
replica), :mod:`.objective` (spacing error and the fits' objectives), :mod:`.fit` (fits),
:mod:`.result` (the fitted parameters and their spread),
:mod:`~analysis.calibration.evaluate` (calibrated vs default RMSE), :mod:`.params_file` (TOML),
:mod:`.vtypes` (driver distribution), :mod:`.sumo_replay` (the same pairs in real SUMO, for checks),
:mod:`.sumo_fit` (fits and scores through SUMO: EIDM), :mod:`.classes` (one population vector
per class of the initial time headway).
"""

from analysis.calibration.class_fit import fit_classes
from analysis.calibration.classes import DriverClasses
from analysis.calibration.evaluate import Evaluation, PairScore, evaluate
from analysis.calibration.fit import BOUNDS, FITTED, calibrate, fit_per_pair, fit_population
from analysis.calibration.models import PARAM_NAMES, SUMO_DEFAULTS, CFParams, simulate_follower
from analysis.calibration.pairs import (
    CarFollowingPair,
    PairBatch,
    load_pairs,
    read_pair,
    split_by_follower,
    split_in_time,
)
from analysis.calibration.params_file import load_result, save_result
from analysis.calibration.result import CalibrationResult, PairFit, ParamSpread
from analysis.calibration.sumo_fit import SumoRmse, calibrate_sumo, fit_population_sumo
from analysis.calibration.vtypes import DriverMember, driver_members

__all__ = [
    "BOUNDS", "FITTED", "PARAM_NAMES", "SUMO_DEFAULTS", "CFParams", "CalibrationResult",
    "CarFollowingPair", "DriverClasses", "DriverMember", "Evaluation", "PairBatch", "PairFit", "PairScore",
    "ParamSpread", "SumoRmse", "calibrate", "calibrate_sumo", "driver_members", "evaluate", "fit_classes", "fit_per_pair",
    "fit_population", "fit_population_sumo",
    "load_pairs", "load_result", "read_pair", "save_result", "simulate_follower", "split_by_follower",
    "split_in_time",
]
