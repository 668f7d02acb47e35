"""Calibration check: the ``i80`` scenario's simulated traffic against the real NGSIM pairs.

:func:`run_calibration_check` runs the scenario with its car drivers replaced by the calibrated
driver distribution (:func:`scenarios.calibration.driver_members` of the params file; or with
the scenario's own drivers, ``keep_drivers=True``: the ``i80`` preset already holds a
calibrated distribution), takes the
congested car-following states of the simulation and of the real pairs and compares per
variable

* speed (ft/s), spacing (ft, **bumper to bumper**: the leader's rear bumper minus the
  follower's front bumper) and time headway (s, **front to front** distance / speed, NGSIM's
  Time_Headway): the two-sample Kolmogorov-Smirnov statistic and the Jensen-Shannon
  divergence (base 2) of histograms on common bins.

Both sides are filtered the same way: a leader in the same lane, spacing in (0, 300] ft,
speed in [1, 45] ft/s; the simulated states are further limited to the lanes the real pairs
come from (I-80 lanes 2-6, :data:`REAL_LANES`; lane 1 is the HOV lane, lane 7 the ramp) and
to the study area (``0 <= Local_Y <= main_length_m``; a downstream bottleneck section past it
is not part of the comparison).

plus the spacing RMSE of the calibrated population vs SUMO's defaults on the pairs
(:func:`scenarios.calibration.evaluate`). :func:`compare_distributions` is the comparison alone,
for any simulated table.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from irl.atomic import write_text_atomic
from irl.units import FT_PER_M, M_PER_FT
from scenarios.calibration import CarFollowingPair, evaluate, load_pairs, load_result
from scenarios.calibration.vtypes import driver_members, resample_members, to_vtype_specs
from scenarios.loader import load_scenario
from sim.run import run_scenario

#: Congested car following: speed range (ft/s) and largest spacing (ft) kept.
SPEED_RANGE_FT_S = (1.0, 45.0)
MAX_SPACING_FT = 300.0
HIST_BINS = 40
VARIABLES = ("speed_ft_s", "spacing_ft", "time_headway_s")
#: I-80 lanes the real pairs were recorded on (ngsim_i80_car_following: lanes 2-6).
REAL_LANES = (2, 3, 4, 5, 6)
#: Driver types drawn for the check from a params file with per-pair fits.
N_MEMBERS = 32


@dataclass(frozen=True)
class VariableComparison:
    """One variable: sample sizes, medians, KS statistic and Jensen-Shannon divergence."""

    name: str
    n_sim: int
    n_real: int
    median_sim: float
    median_real: float
    ks: float
    js: float


@dataclass(frozen=True)
class CalibrationCheck:
    """The report."""

    scenario: str
    seed: int
    duration_s: float
    model: str
    variables: tuple[VariableComparison, ...]
    median_rmse_m: float
    default_median_rmse_m: float
    mean_rmse_m: float
    default_mean_rmse_m: float
    n_pairs: int

    def to_json_dict(self) -> dict:
        d = asdict(self)
        d["variables"] = {v.name: {k: x for k, x in asdict(v).items() if k != "name"} for v in self.variables}
        return d

    def to_markdown(self) -> str:
        lines = [
            f"# Calibration check: scenario `{self.scenario}` (seed {self.seed}, {self.duration_s:g} s) vs real NGSIM I-80 pairs",
            "",
            "Congested car following (I-80 lanes 2-6 of the study area, leader within 300 ft, 1-45 ft/s); "
            "spacing bumper to bumper, time headway front to front / speed.",
            "",
            "| variable | n sim | n real | median sim | median real | KS | Jensen-Shannon |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        for v in self.variables:
            lines.append(f"| {v.name} | {v.n_sim} | {v.n_real} | {v.median_sim:.2f} | {v.median_real:.2f} | "
                         f"{v.ks:.3f} | {v.js:.3f} |")
        lines += [
            "",
            f"Spacing RMSE on {self.n_pairs} real pairs ({self.model}): calibrated median "
            f"{self.median_rmse_m:.2f} m (mean {self.mean_rmse_m:.2f}) vs SUMO defaults median "
            f"{self.default_median_rmse_m:.2f} m (mean {self.default_mean_rmse_m:.2f}).",
            "",
        ]
        return "\n".join(lines)

    def write_markdown(self, path: str | os.PathLike) -> Path:
        return write_text_atomic(path, self.to_markdown())


def _congested(speed: np.ndarray, spacing: np.ndarray, headway_front: np.ndarray) -> dict[str, np.ndarray]:
    ok = (speed >= SPEED_RANGE_FT_S[0]) & (speed <= SPEED_RANGE_FT_S[1]) & (spacing > 0) & (spacing <= MAX_SPACING_FT)
    return {"speed_ft_s": speed[ok], "spacing_ft": spacing[ok], "time_headway_s": headway_front[ok] / speed[ok]}


def table_states(table: pd.DataFrame, *, lanes: tuple[int, ...] = REAL_LANES,
                 study_length_ft: float = np.inf) -> dict[str, np.ndarray]:
    """Congested following states of a trajectory table (NGSIM units); float64[n] per variable.

    Spacing = ``Space_Headway`` (front to front, ft) minus the preceding vehicle's ``v_Length``
    (bumper to bumper); time headway = ``Space_Headway / v_Vel``. Rows on ``lanes`` with
    ``0 <= Local_Y <= study_length_ft`` and a preceding vehicle are kept.
    """
    y = table["Local_Y"]
    t = table[table["Lane_ID"].isin(lanes) & (table["Preceding"] != 0) & (y >= 0) & (y <= study_length_ft)]
    lengths = table.drop_duplicates("Vehicle_ID").set_index("Vehicle_ID")["v_Length"]
    lead_len = t["Preceding"].map(lengths).to_numpy(dtype=float)
    front = t["Space_Headway"].to_numpy(dtype=float)
    spacing = front - np.nan_to_num(lead_len, nan=np.inf)
    return _congested(t["v_Vel"].to_numpy(dtype=float), spacing, front)


def pair_states(pairs: list[CarFollowingPair]) -> dict[str, np.ndarray]:
    """The same variables from the real pairs (converted back to feet): the pairs' ``spacing``
    is bumper to bumper (``x_leader - x_follower - leader_length``, positions of the front
    bumpers), front to front adds the leader's length back."""
    v = np.concatenate([p.v_follower for p in pairs]) / M_PER_FT
    s = np.concatenate([p.spacing for p in pairs]) / M_PER_FT
    front = np.concatenate([p.spacing + p.leader_length for p in pairs]) / M_PER_FT
    return _congested(v, s, front)


def _js(a: np.ndarray, b: np.ndarray) -> float:
    lo, hi = np.quantile(np.concatenate([a, b]), [0.005, 0.995])
    edges = np.linspace(lo, hi, HIST_BINS + 1)
    p = np.histogram(np.clip(a, lo, hi), edges)[0].astype(float) + 1e-12
    q = np.histogram(np.clip(b, lo, hi), edges)[0].astype(float) + 1e-12
    p, q = p / p.sum(), q / q.sum()
    m = 0.5 * (p + q)
    return float(0.5 * np.sum(p * np.log2(p / m)) + 0.5 * np.sum(q * np.log2(q / m)))


def compare_distributions(sim: dict[str, np.ndarray], real: dict[str, np.ndarray]) -> tuple[VariableComparison, ...]:
    from scipy.stats import ks_2samp

    out = []
    for name in VARIABLES:
        a, b = sim[name], real[name]
        if len(a) == 0 or len(b) == 0:
            out.append(VariableComparison(name, len(a), len(b), float("nan"), float("nan"), float("nan"), float("nan")))
            continue
        out.append(VariableComparison(
            name=name, n_sim=len(a), n_real=len(b), median_sim=float(np.median(a)), median_real=float(np.median(b)),
            ks=float(ks_2samp(a, b).statistic), js=_js(a, b),
        ))
    return tuple(out)


def calibrated_spec(spec, result, *, n_members: int = N_MEMBERS, seed: int = 0):
    """``spec`` with its car vTypes replaced by the calibrated driver distribution: a resample
    of the per-pair parameter vectors (:func:`resample_members`) when ``result`` has them, else
    the population alone."""
    members = resample_members(result, n_members, seed=seed) if result.per_pair else driver_members(result, 1)
    cars = to_vtype_specs(members, spec.drivers.car[0], result.model)
    return replace(spec, drivers=replace(spec.drivers, car=cars))


def run_calibration_check(
    *, params_path: str | os.PathLike, pairs_dir: str | os.PathLike, scenario: str = "i80",
    duration_s: float | None = None, seed: int = 0, table: pd.DataFrame | None = None,
    keep_drivers: bool = False,
) -> CalibrationCheck:
    """Simulate ``scenario`` with the calibrated drivers (the scenario's own with
    ``keep_drivers``; nothing is simulated when ``table`` is given) and compare.
    ``duration_s`` None = the scenario's own duration.

    Raises:
        FileNotFoundError: ``params_path`` or ``pairs_dir`` does not exist.
        SpecError: ``params_path`` is not valid TOML, ``pairs_dir`` holds no pair CSV files, or ``scenario``
            is no preset nor scenario file.
        SimulationError: SUMO fails to start or to step.
    """
    result = load_result(params_path)
    pairs = list(load_pairs(Path(pairs_dir)))
    spec = load_scenario(scenario)
    if table is None:
        if not keep_drivers:
            spec = calibrated_spec(spec, result, seed=seed)
        table = run_scenario(spec, seed=seed, duration_s=duration_s).table
    if duration_s is None:
        duration_s = spec.simulation.duration_s
    ev = evaluate(result.population, pairs, model=result.model)
    return CalibrationCheck(
        scenario=str(scenario), seed=seed, duration_s=duration_s, model=result.model,
        variables=compare_distributions(table_states(table, study_length_ft=spec.road.main_length_m * FT_PER_M),
                                        pair_states(pairs)),
        median_rmse_m=ev.median_rmse_m, default_median_rmse_m=ev.default_median_rmse_m,
        mean_rmse_m=ev.mean_rmse_m, default_mean_rmse_m=ev.default_mean_rmse_m, n_pairs=len(pairs),
    )
