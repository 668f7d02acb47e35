"""Calibration check: the ``i80`` scenario's simulated traffic against the real NGSIM pairs.

:func:`run_calibration_check` runs the scenario with its car drivers replaced by the calibrated
driver distribution (:func:`analysis.calibration.driver_members` of the params file; or with
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
(:func:`analysis.calibration.evaluate`). :func:`compare_distributions` is the comparison alone,
for any simulated table.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from merge_irl.atomic import write_text_atomic
from merge_irl.units import FT_PER_M, M_PER_FT
from analysis.calibration import CarFollowingPair, evaluate, load_pairs, load_result
from analysis.calibration.vtypes import driver_members, resample_members, scenario_car_model, to_vtype_specs
from scenarios.loader import load_scenario
from sim.run import run_scenario
from sim.schema import RAMP_LANE, RIGHTMOST_MAIN_LANE

#: Congested car following: speed range (ft/s) and largest spacing (ft) kept.
SPEED_RANGE_FT_S = (1.0, 45.0)
MAX_SPACING_FT = 300.0
HIST_BINS = 40
VARIABLES = ("speed_ft_s", "spacing_ft", "time_headway_s")
#: I-80 lanes the real pairs were recorded on (ngsim_i80_car_following: lanes 2-6).
REAL_LANES = (2, 3, 4, 5, 6)
#: Driver types drawn for the check from a params file with per-pair fits.
N_MEMBERS = 32
#: Issue 14's target: KS distance at most this for each variable.
KS_TARGET = 0.15
#: Quantiles of the accepted-gap summary.
GAP_QUANTILES = (0.1, 0.25, 0.5, 0.75, 0.9)


@dataclass(frozen=True)
class AcceptedGaps:
    """Gaps ramp cars accepted: at the first frame a car seen on the ramp / auxiliary lane
    (lane 7) is in lane 6, bumper-to-bumper distances (ft) to the lag car A behind it
    (``lag``: B's rear bumper minus A's front bumper), to the lead car C ahead (``lead``: C's
    rear minus B's front) and between them (``total``: C's rear minus A's front). float64[n]
    each, NaN where there is no such car in lane 6.
    """

    lag_ft: np.ndarray
    lead_ft: np.ndarray
    total_ft: np.ndarray

    @property
    def n(self) -> int:
        return len(self.total_ft)

    def quantiles(self) -> dict[str, list[float]]:
        """name -> the :data:`GAP_QUANTILES` of the finite values (NaN when there are none)."""
        out = {}
        for name in ("lag_ft", "lead_ft", "total_ft"):
            x = getattr(self, name)
            x = x[np.isfinite(x)]
            out[name] = [float(q) for q in np.quantile(x, GAP_QUANTILES)] if len(x) else [float("nan")] * len(GAP_QUANTILES)
        return out


def _vehicle_lengths(table: pd.DataFrame) -> pd.Series:
    """Vehicle_ID -> v_Length (ft) of a trajectory table (first row of each vehicle)."""
    return table.drop_duplicates("Vehicle_ID").set_index("Vehicle_ID")["v_Length"]


def accepted_gaps(table: pd.DataFrame) -> AcceptedGaps:
    """The gaps accepted by the ramp cars of a trajectory table (NGSIM schema, ft); see
    :class:`AcceptedGaps`. Cars never seen on lane 7 before lane 6 are left out."""
    t = table.sort_values(["Vehicle_ID", "Frame_ID"], kind="stable")
    on_ramp = t["Lane_ID"] == RAMP_LANE
    was_ramp = on_ramp.groupby(t["Vehicle_ID"]).cummax()
    merged = t[(t["Lane_ID"] == RIGHTMOST_MAIN_LANE) & was_ramp].drop_duplicates("Vehicle_ID")
    where = table.set_index(["Vehicle_ID", "Frame_ID"])["Local_Y"]
    lengths = _vehicle_lengths(table)

    def y_of(ids: pd.Series) -> np.ndarray:
        keys = list(zip(ids.to_numpy(), merged["Frame_ID"].to_numpy()))
        return np.array([where.get(k, np.nan) if k[0] != 0 else np.nan for k in keys], dtype=float)

    y_b = merged["Local_Y"].to_numpy(dtype=float)
    len_b = merged["v_Length"].to_numpy(dtype=float)
    y_a = y_of(merged["Following"])
    y_c = y_of(merged["Preceding"])
    len_c = merged["Preceding"].map(lengths).to_numpy(dtype=float)
    return AcceptedGaps(lag_ft=y_b - len_b - y_a, lead_ft=y_c - len_c - y_b, total_ft=y_c - len_c - y_a)


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
    #: name ("lag_ft", "lead_ft", "total_ft") -> :data:`GAP_QUANTILES` of the simulated accepted gaps.
    accepted_gap_quantiles: dict | None = None
    n_merges: int = 0
    #: True: the scenario's own car drivers were simulated (``--keep-drivers``), not the params file's.
    keep_drivers: bool = False

    def to_json_dict(self) -> dict:
        d = asdict(self)
        d["variables"] = {v.name: {k: x for k, x in asdict(v).items() if k != "name"} | {"ks_target_met": v.ks <= KS_TARGET}
                          for v in self.variables}
        return d

    def to_markdown(self) -> str:
        lines = [
            f"# Calibration check: scenario `{self.scenario}` (seed {self.seed}, {self.duration_s:g} s) vs real NGSIM I-80 pairs",
            "",
            "Simulated car drivers: " + ("the scenario's own (--keep-drivers)." if self.keep_drivers else
                                         f"resampled from the params file ({self.model})."),
            "",
            "Congested car following (I-80 lanes 2-6 of the study area, leader within 300 ft, 1-45 ft/s); "
            "spacing bumper to bumper, time headway front to front / speed.",
            "",
            f"| variable | n sim | n real | median sim | median real | KS | KS <= {KS_TARGET:g} | Jensen-Shannon |",
            "|---|---:|---:|---:|---:|---:|---|---:|",
        ]
        for v in self.variables:
            lines.append(f"| {v.name} | {v.n_sim} | {v.n_real} | {v.median_sim:.2f} | {v.median_real:.2f} | "
                         f"{v.ks:.3f} | {'yes' if v.ks <= KS_TARGET else 'no'} | {v.js:.3f} |")
        if self.accepted_gap_quantiles:
            qs = " / ".join(f"{int(100 * q)} %" for q in GAP_QUANTILES)
            lines += ["", f"Gaps accepted by the {self.n_merges} simulated ramp merges, bumper to bumper in lane 6 "
                          f"(ft; {qs}; no real merges to compare with in the pair data):", ""]
            for name, vals in self.accepted_gap_quantiles.items():
                lines.append(f"- {name}: " + " / ".join(f"{x:.1f}" for x in vals))
        lines += [
            "",
            f"Spacing RMSE on {self.n_pairs} real pairs of the params file's population ({self.model}): calibrated median "
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
    lengths = _vehicle_lengths(table)
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


def calibrated_spec(spec, result, *, n_members: int = N_MEMBERS, seed: int = 0, car_follow_model: str | None = None):
    """``spec`` with its car vTypes replaced by the calibrated driver distribution: a resample
    of the per-pair parameter vectors (:func:`resample_members`) when ``result`` has them, else
    the population alone, driven by SUMO model ``car_follow_model`` (None:
    :func:`~analysis.calibration.vtypes.scenario_car_model`, the scenario's own when it takes the
    fitted parameters, e.g. the ``i80`` preset's EIDM for IDM fits) with the scenario's driver
    noise (:func:`~analysis.calibration.vtypes.to_vtype_specs`)."""
    members = resample_members(result, n_members, seed=seed) if result.per_pair else driver_members(result, 1)
    if car_follow_model is None:
        car_follow_model = scenario_car_model(result.model, [c.car_follow_model for c in spec.drivers.car])
    cars = to_vtype_specs(members, spec.drivers.car[0], result.model, car_follow_model=car_follow_model)
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
    gaps = accepted_gaps(table)
    return CalibrationCheck(
        scenario=str(scenario), seed=seed, duration_s=duration_s, model=result.model,
        variables=compare_distributions(table_states(table, study_length_ft=spec.road.main_length_m * FT_PER_M),
                                        pair_states(pairs)),
        median_rmse_m=ev.median_rmse_m, default_median_rmse_m=ev.default_median_rmse_m,
        mean_rmse_m=ev.mean_rmse_m, default_mean_rmse_m=ev.default_mean_rmse_m, n_pairs=len(pairs),
        accepted_gap_quantiles=gaps.quantiles(), n_merges=gaps.n, keep_drivers=keep_drivers,
    )
