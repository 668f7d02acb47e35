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
from analysis.calibration.vtypes import (
    driver_members, every_member, resample_members, scenario_car_model, to_vtype_specs,
)
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.runtime.run import run_scenario
from sim.runtime.schema import RAMP_LANE, RIGHTMOST_MAIN_LANE

#: Congested car following: speed range (ft/s) and largest spacing (ft) kept.
SPEED_RANGE_FT_S = (1.0, 45.0)
MAX_SPACING_FT = 300.0
HIST_BINS = 40
VARIABLES = ("speed_ft_s", "spacing_ft", "time_headway_s")
#: I-80 lanes the real pairs were recorded on (ngsim_i80_car_following: lanes 2-6).
REAL_LANES = (2, 3, 4, 5, 6)
#: Driver types of a resample (``n_members``) from a params file with per-pair fits; the ``i80``
#: preset has 32. The default is every per-pair fit once (:func:`~.vtypes.every_member`).
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
    """One variable: sample sizes, medians, KS statistic and Jensen-Shannon divergence; the
    interquartile ranges and the KS statistics that remain once the simulated sample is moved to
    the real median (``ks_shifted``) and also scaled to the real interquartile range
    (``ks_rescaled``), which :func:`diagnose` reads."""

    name: str
    n_sim: int
    n_real: int
    median_sim: float
    median_real: float
    ks: float
    js: float
    iqr_sim: float = float("nan")
    iqr_real: float = float("nan")
    ks_shifted: float = float("nan")
    ks_rescaled: float = float("nan")


#: What a miss of each kind points to (docs/calibration.md, *Which variable misses and why*).
CAUSES = {"ok": "-", "location": "demand", "spread": "driver spread", "shape": "model"}
_LOCATION_HINT = {
    "speed_ft_s": "the traffic state: demand per lane, the bottleneck, the drivers' desired speed (maxSpeed)",
    "spacing_ft": "the density: demand per lane and the bottleneck, or the drivers' minGap / tau",
    "time_headway_s": "the density: demand per lane and the bottleneck, or the drivers' tau",
}


@dataclass(frozen=True)
class Diagnosis:
    """Why one variable misses the KS target (:func:`diagnose`).

    ``kind``: ``"ok"`` (KS within the target), ``"location"`` (moving the simulated sample to the
    real median brings it within), ``"spread"`` (moving it and scaling it to the real
    interquartile range brings it within), ``"shape"`` (neither); ``cause`` the likely why,
    :data:`CAUSES` of the kind; ``text`` one sentence with the measured signals.
    """

    variable: str
    kind: str
    cause: str
    text: str


def diagnose(variables, target: float | None = None) -> tuple[Diagnosis, ...]:
    """A :class:`Diagnosis` per :class:`VariableComparison`, from measured signals only.

    Rule (applied in this order to a variable whose KS exceeds ``target``, default
    :data:`KS_TARGET`): if ``ks_shifted <= target`` the two distributions differ mainly by a
    location shift, which points to the demand (the traffic state the drivers are in: flow per
    lane, bottleneck, desired speed); else if ``ks_rescaled <= target`` they differ in width
    (interquartile range), which points to the driver spread (how much the simulated drivers
    differ from one another, or oscillate); else the shape differs (e.g. two modes where the
    real has one), which points to the car-following model. NaN comparisons (an empty sample)
    give kind ``"shape"`` with the cause ``"no data"``.
    """
    target = KS_TARGET if target is None else target
    out = []
    for v in variables:
        if not np.isfinite(v.ks):
            out.append(Diagnosis(v.name, "shape", "no data", f"{v.name}: no simulated or real states to compare"))
            continue
        if v.ks <= target:
            out.append(Diagnosis(v.name, "ok", CAUSES["ok"], f"{v.name}: KS {v.ks:.3f} <= {target:g}"))
            continue
        offset = (f"median {v.median_sim:.2f} vs {v.median_real:.2f} real "
                  f"({'higher' if v.median_sim > v.median_real else 'lower'})")
        ratio = v.iqr_sim / v.iqr_real if v.iqr_real > 0 else float("nan")
        width = f"interquartile range {v.iqr_sim:.2f} vs {v.iqr_real:.2f} real (x{ratio:.2f}, " + (
            "narrower)" if ratio < 1 else "wider)")
        signals = (f"KS {v.ks:.3f}; at the real median {v.ks_shifted:.3f}, also at the real width "
                   f"{v.ks_rescaled:.3f}")
        if v.ks_shifted <= target:
            kind, why = "location", f"a location shift, {offset}: check {_LOCATION_HINT.get(v.name, 'the demand')}"
        elif v.ks_rescaled <= target:
            kind, why = "spread", (f"a width mismatch, {width}: the simulated drivers differ "
                                   f"{'too little' if ratio < 1 else 'too much'} (driver spread)")
        else:
            kind, why = "shape", (f"a shape the median and width do not explain ({offset}; {width}): "
                                  "the car-following model (e.g. two modes where the real has one)")
        out.append(Diagnosis(v.name, kind, CAUSES[kind], f"{v.name} misses: {why} [{signals}]"))
    return tuple(out)


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
    #: SUMO car-following model(s) of the simulated car drivers ("EIDM", or "EIDM, IDM" for a mix).
    car_follow_model: str = ""

    def diagnoses(self) -> tuple[Diagnosis, ...]:
        """:func:`diagnose` of the variables."""
        return diagnose(self.variables)

    def to_json_dict(self) -> dict:
        d = asdict(self)
        why = {g.variable: g for g in self.diagnoses()}
        d["variables"] = {v.name: {k: x for k, x in asdict(v).items() if k != "name"}
                          | {"ks_target_met": v.ks <= KS_TARGET,
                             "diagnosis": {"kind": why[v.name].kind, "cause": why[v.name].cause, "text": why[v.name].text}}
                          for v in self.variables}
        d["misses"] = [g.variable for g in self.diagnoses() if g.kind != "ok"]
        return d

    def to_markdown(self) -> str:
        lines = [
            f"# Calibration check: scenario `{self.scenario}` (seed {self.seed}, {self.duration_s:g} s) vs real NGSIM I-80 pairs",
            "",
            "Simulated car drivers: " + ("the scenario's own (--keep-drivers)" if self.keep_drivers else
                                         f"resampled from the params file ({self.model})")
            + (f", SUMO's {self.car_follow_model}." if self.car_follow_model else "."),
            "",
            "Congested car following (I-80 lanes 2-6 of the study area, leader within 300 ft, 1-45 ft/s); "
            "spacing bumper to bumper, time headway front to front / speed.",
            "",
            f"| variable | n sim | n real | median sim | median real | KS | KS <= {KS_TARGET:g} | Jensen-Shannon | likely why |",
            "|---|---:|---:|---:|---:|---:|---|---:|---|",
        ]
        why = {g.variable: g for g in self.diagnoses()}
        for v in self.variables:
            lines.append(f"| {v.name} | {v.n_sim} | {v.n_real} | {v.median_sim:.2f} | {v.median_real:.2f} | "
                         f"{v.ks:.3f} | {'yes' if v.ks <= KS_TARGET else 'no'} | {v.js:.3f} | {why[v.name].cause} |")
        misses = [g for g in self.diagnoses() if g.kind != "ok"]
        if misses:
            lines += ["", f"Misses of the KS target ({len(misses)}; rule in docs/calibration.md, *Which variable misses "
                          "and why*):", ""] + [f"- {g.text}" for g in misses]
        elif self.variables:
            lines += ["", "Every variable meets the KS target."]
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
        med_a, med_b = float(np.median(a)), float(np.median(b))
        iqr_a, iqr_b = (float(np.subtract(*np.quantile(x, [0.75, 0.25]))) for x in (a, b))
        shifted = a - med_a + med_b
        rescaled = (a - med_a) * (iqr_b / iqr_a) + med_b if iqr_a > 0 else shifted
        out.append(VariableComparison(
            name=name, n_sim=len(a), n_real=len(b), median_sim=med_a, median_real=med_b,
            ks=float(ks_2samp(a, b).statistic), js=_js(a, b), iqr_sim=iqr_a, iqr_real=iqr_b,
            ks_shifted=float(ks_2samp(shifted, b).statistic), ks_rescaled=float(ks_2samp(rescaled, b).statistic),
        ))
    return tuple(out)


def calibrated_spec(spec, result, *, n_members: int | None = None, seed: int = 0,
                    car_follow_model: str | None = None):
    """``spec`` with its car vTypes replaced by the calibrated driver distribution: when
    ``result`` has per-pair fits, every one of them once (``n_members`` None,
    :func:`every_member`) or ``n_members`` resampled with ``seed`` (:func:`resample_members`),
    else the population alone; driven by SUMO model ``car_follow_model`` (None:
    :func:`~analysis.calibration.vtypes.scenario_car_model`, the scenario's own when it takes the
    fitted parameters, e.g. the ``i80`` preset's EIDM for IDM fits) with the scenario's driver
    noise (:func:`~analysis.calibration.vtypes.to_vtype_specs`)."""
    if not result.per_pair:
        members = driver_members(result, 1)
    elif n_members is None:
        members = every_member(result)
    else:
        members = resample_members(result, n_members, seed=seed)
    if car_follow_model is None:
        car_follow_model = scenario_car_model(result.model, [c.car_follow_model for c in spec.drivers.car])
    cars = to_vtype_specs(members, spec.drivers.car[0], result.model, car_follow_model=car_follow_model)
    return replace(spec, drivers=replace(spec.drivers, car=cars))


def run_calibration_check(
    *, params_path: str | os.PathLike, pairs_dir: str | os.PathLike, scenario: str = "i80",
    duration_s: float | None = None, seed: int = 0, table: pd.DataFrame | None = None,
    keep_drivers: bool = False, n_drivers: int | None = None, allow_implausible: bool = False,
) -> CalibrationCheck:
    """Simulate ``scenario`` with the calibrated drivers (:func:`calibrated_spec`: every per-pair
    fit once, or ``n_drivers`` resampled with ``seed``; the scenario's own with ``keep_drivers``;
    nothing is simulated when ``table`` is given) and compare.
    ``duration_s`` None = the scenario's own duration; ``allow_implausible``: run values outside
    the plausibility bounds (:mod:`scenarios.spec.bounds`).

    Raises:
        FileNotFoundError: ``params_path`` or ``pairs_dir`` does not exist.
        SpecError: ``params_path`` is not valid TOML, ``pairs_dir`` holds no pair CSV files, or ``scenario``
            is no preset nor scenario file.
        SimulationError: SUMO fails to start or to step.
    """
    result = load_result(params_path)
    pairs = list(load_pairs(Path(pairs_dir)))
    spec = load_scenario(scenario, allow_implausible=allow_implausible)
    if duration_s is not None:
        with_overrides(spec, duration_s=duration_s)  # a duration the scenario rejects: before the SUMO run
    if not keep_drivers:
        spec = calibrated_spec(spec, result, n_members=n_drivers, seed=seed)
    if table is None:
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
        car_follow_model=", ".join(sorted({c.car_follow_model for c in spec.drivers.car})),
    )
