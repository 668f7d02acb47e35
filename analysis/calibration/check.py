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
for any simulated table (:mod:`analysis.calibration.compare`, with :func:`diagnose`); the states
compared and the accepted gaps: :mod:`analysis.calibration.states`.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import pandas as pd

from analysis.calibration import evaluate, load_pairs, load_result
from analysis.calibration.compare import KS_TARGET, Diagnosis, VariableComparison, compare_distributions, diagnose
from analysis.calibration.states import GAP_QUANTILES, accepted_gaps, pair_states, table_states
from analysis.calibration.vtypes import (
    driver_members,
    every_member,
    resample_members,
    scenario_car_model,
    to_vtype_specs,
)
from merge_irl.atomic import write_text_atomic
from merge_irl.units import FT_PER_M
from scenarios.errors import SpecError
from scenarios.loader import load_scenario
from scenarios.spec.parse import with_overrides
from sim.runtime.run import run_scenario
from sim.runtime.sites import site_of

__all__ = ["N_MEMBERS", "CalibrationCheck", "calibrated_spec", "run_calibration_check"]

#: Driver types of a resample (``n_members``) from a params file with per-pair fits; the ``i80``
#: preset has 32. The default is every per-pair fit once (:func:`~.vtypes.every_member`).
N_MEMBERS = 32


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


def heldout_pairs(pairs, result, params_path, pairs_dir) -> list:
    """The ``pairs`` whose follower ``result`` was not fitted on (its ``train_followers``).

    Raises:
        SpecError: the params file records no training followers, or every pair's follower was
            in the fit (each naming the fix: ``calibrate fit --holdout F``).
    """
    trained = set(result.train_followers)
    if not trained:
        raise SpecError(f"--heldout-only: {params_path} does not record the followers it was fitted on; refit with "
                        "'calibrate fit --holdout F --seed S' to keep pairs aside")
    unseen = [p for p in pairs if p.group not in trained]
    if not unseen:
        raise SpecError(f"--heldout-only: every pair of {pairs_dir} has a follower {params_path} was fitted on; "
                        "fit with 'calibrate fit --holdout F --seed S' on this folder to keep some aside")
    return unseen


def run_calibration_check(
    *, params_path: str | os.PathLike, pairs_dir: str | os.PathLike, scenario: str = "i80",
    duration_s: float | None = None, seed: int = 0, table: pd.DataFrame | None = None,
    keep_drivers: bool = False, n_drivers: int | None = None, allow_implausible: bool = False,
    heldout_only: bool = False,
) -> CalibrationCheck:
    """Simulate ``scenario`` with the calibrated drivers (:func:`calibrated_spec`: every per-pair
    fit once, or ``n_drivers`` resampled with ``seed``; the scenario's own with ``keep_drivers``;
    nothing is simulated when ``table`` is given) and compare.
    ``duration_s`` None = the scenario's own duration; ``allow_implausible``: run values outside
    the plausibility bounds (:mod:`scenarios.spec.bounds`). ``heldout_only``: compare with the
    pairs whose follower the params file was not fitted on (its recorded training followers;
    ``calibrate fit --holdout``), so the check is of drivers against traffic they did not see.

    Raises:
        FileNotFoundError: ``params_path`` or ``pairs_dir`` does not exist.
        SpecError: ``params_path`` is not valid TOML, ``pairs_dir`` holds no pair CSV files, ``scenario``
            is no preset nor scenario file, or ``heldout_only`` finds no pair left (:func:`heldout_pairs`).
        SimulationError: SUMO fails to start or to step.
    """
    result = load_result(params_path)
    pairs = list(load_pairs(Path(pairs_dir)))
    if heldout_only:
        pairs = heldout_pairs(pairs, result, params_path, pairs_dir)
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
    gaps = accepted_gaps(table, site=site_of(spec))
    return CalibrationCheck(
        scenario=str(scenario), seed=seed, duration_s=duration_s, model=result.model,
        variables=compare_distributions(table_states(table, study_length_ft=spec.road.main_length_m * FT_PER_M),
                                        pair_states(pairs)),
        median_rmse_m=ev.median_rmse_m, default_median_rmse_m=ev.default_median_rmse_m,
        mean_rmse_m=ev.mean_rmse_m, default_mean_rmse_m=ev.default_mean_rmse_m, n_pairs=len(pairs),
        accepted_gap_quantiles=gaps.quantiles(), n_merges=gaps.n, keep_drivers=keep_drivers,
        car_follow_model=", ".join(sorted({c.car_follow_model for c in spec.drivers.car})),
    )
