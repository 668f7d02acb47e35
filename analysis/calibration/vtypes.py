"""Calibrated driver population -> a distribution of SUMO vTypes (so drivers differ).

:func:`resample_members` (used when the per-pair fits exist) draws whole per-pair parameter
vectors, so the members keep the fitted joint distribution (a driver with a short time
headway keeps the acceleration fitted with it); each vector is clipped to :data:`SIM_RANGE`.

:func:`driver_members` (the fallback with only the spread) draws members from a log-normal per parameter centred on the population value, with the
log-spread of the per-pair fits' 10-90 % range (``sigma = (ln q90 - ln q10) / 2.563``),
truncated to that range and to :data:`SIM_RANGE` (per-pair fits of badly identified
parameters reach the fit bounds, e.g. decel 0.1 m/s^2, which would make SUMO's safety logic
misbehave). Parameters are drawn independently; deterministic for a given seed.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from analysis.calibration.fit import FITTED
from analysis.calibration.models import CALIBRATION_MODELS, EIDM_NOISE_OFF, CFParams
from analysis.calibration.result import CalibrationResult

#: Range allowed in simulation (SI units).
SIM_RANGE: dict[str, tuple[float, float]] = {
    "accel": (0.5, 4.0),
    "decel": (1.0, 6.0),
    "tau": (0.5, 2.5),
    "minGap": (1.0, 5.0),
    "maxSpeed": (15.0, 40.0),
    "delta": (2.0, 8.0),
}
_Z90 = 1.2815515655446004


@dataclass(frozen=True)
class DriverMember:
    """One vType of the distribution: its id, probability and car-following parameters."""

    id: str
    probability: float
    params: CFParams


def driver_members(result: CalibrationResult, n: int = 8, *, seed: int = 0, prefix: str = "car_ngsim") -> tuple[DriverMember, ...]:
    """``n`` equally likely members; member 0 is the population (both clipped to :data:`SIM_RANGE`).

    Raises:
        ValueError: ``n`` < 1.
    """
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    rng = np.random.default_rng(seed)
    spread = dict(result.spread)
    pop = replace(result.population, **{
        k: float(min(max(getattr(result.population, k), lo), hi)) for k, (lo, hi) in SIM_RANGE.items()})
    members = [DriverMember(f"{prefix}_0", 1.0 / n, pop)]
    for i in range(1, n):
        vals = {}
        for name in result.fitted:
            centre = getattr(pop, name)
            lo, hi = SIM_RANGE.get(name, (centre, centre))
            if name in spread and spread[name].q10 > 0 and spread[name].q90 > spread[name].q10:
                s = spread[name]
                sigma = (np.log(s.q90) - np.log(s.q10)) / (2 * _Z90)
                val = float(np.exp(np.log(centre) + sigma * rng.standard_normal()))
                val = min(max(val, s.q10), s.q90)
            else:
                val = centre
            vals[name] = float(min(max(val, lo), hi))
        members.append(DriverMember(f"{prefix}_{i}", 1.0 / n, replace(pop, **vals)))
    return tuple(members)


def resample_members(result: CalibrationResult, n: int = 32, *, seed: int = 0,
                     prefix: str = "car_ngsim") -> tuple[DriverMember, ...]:
    """``n`` equally likely members, each the parameter vector of one per-pair fit drawn with
    replacement (``numpy.random.default_rng(seed)``; pairs equally likely), clipped to
    :data:`SIM_RANGE`: a bootstrap of the fitted joint distribution. Deterministic per seed.

    Raises:
        ValueError: ``n`` < 1, or ``result`` holds no per-pair fits.
    """
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if not result.per_pair:
        raise ValueError("the calibration result holds no per-pair fits to resample (fit without --no-per-pair)")
    idx = np.random.default_rng(seed).integers(0, len(result.per_pair), size=n)
    out = []
    for i, k in enumerate(idx):
        p = result.per_pair[int(k)].params
        clipped = {name: float(min(max(getattr(p, name), lo), hi)) for name, (lo, hi) in SIM_RANGE.items()}
        out.append(DriverMember(f"{prefix}_{i}", 1.0 / n, replace(p, **clipped)))
    return tuple(out)


def every_member(result: CalibrationResult, *, prefix: str = "car_ngsim") -> tuple[DriverMember, ...]:
    """One equally likely member per per-pair fit, in the params file's order, each clipped to
    :data:`SIM_RANGE`: the fitted joint distribution itself, with no resampling noise (a 32-member
    bootstrap of 208 fits moved the held-out speed KS of the ``i80`` scenario by up to 0.14,
    docs/calibration.md). Deterministic.

    Raises:
        ValueError: ``result`` holds no per-pair fits.
    """
    if not result.per_pair:
        raise ValueError("the calibration result holds no per-pair fits (fit without --no-per-pair)")
    n = len(result.per_pair)
    out = []
    for i, f in enumerate(result.per_pair):
        clipped = {name: float(min(max(getattr(f.params, name), lo), hi)) for name, (lo, hi) in SIM_RANGE.items()}
        out.append(DriverMember(f"{prefix}_{i}", 1.0 / n, replace(f.params, **clipped)))
    return tuple(out)


def member_spread(members) -> dict[str, tuple[float, float, float]]:
    """(10 %, 50 %, 90 %) quantiles of each fitted parameter over ``members`` (equal weights).

    Args:
        members: sequence of :class:`DriverMember`.
    Returns:
        parameter name -> (q10, median, q90), SI units.
    """
    out: dict[str, tuple[float, float, float]] = {}
    for name in FITTED:
        q10, q50, q90 = np.quantile([getattr(m.params, name) for m in members], [0.1, 0.5, 0.9])
        out[name] = (float(q10), float(q50), float(q90))
    return out


#: SUMO car-following models that take the IDM parameters (accel, decel, tau, minGap, maxSpeed,
#: delta) with the same meaning: EIDM and IIDM extend SUMO's IDM.
IDM_FAMILY = ("IDM", "IIDM", "EIDM")


def scenario_car_model(fitted_model: str, scenario_models) -> str:
    """The SUMO ``carFollowModel`` a scenario's calibrated car drivers use.

    The scenario's own car model when all its car types share one and it takes the fitted
    parameters with the same meaning (:data:`IDM_FAMILY`: IDM fits driven by the ``i80``
    preset's EIDM, as the preset was made); otherwise the fitted model's own SUMO model.

    Args:
        fitted_model: a params file's ``model`` (``"idm"``, ``"krauss"``, ``"eidm"``).
        scenario_models: the scenario's car types' ``car_follow_model`` values.
    Returns:
        a SUMO model name (``"IDM"``, ``"EIDM"``, ``"Krauss"``, ...).
    """
    fitted = CALIBRATION_MODELS[fitted_model]
    own = set(scenario_models)
    if len(own) == 1 and fitted in IDM_FAMILY and (m := own.pop()) in IDM_FAMILY:
        return m
    return fitted


def to_vtype_specs(members, template, model: str = "idm", *, car_follow_model: str | None = None):
    """The members as :class:`scenarios.spec.model.VTypeSpec` of SUMO model ``model`` ("idm" /
    "krauss" / "eidm", EIDM with its noise off as in the fit), other attributes (length, width, lane-change model) from ``template``;
    speedFactor 1 and speedDev 0, so ``maxSpeed`` is the desired speed as in the fit.

    ``car_follow_model`` (a SUMO model name, e.g. from :func:`scenario_car_model`): the members
    are a scenario's drivers, driven by that model; under EIDM they keep the template's driver
    noise keys (``sigmaleader``, ``sigmagap``, ``sigmaerror``), so with none written SUMO's default
    noise, as in the ``i80`` preset (the fit turns the noise off only to replay a pair
    deterministically; in a scenario it is part of the traffic, docs/calibration.md *Why EIDM*).

    Args:
        members: sequence of :class:`DriverMember`.
        template: a ``scenarios.spec.model.VTypeSpec`` (e.g. the scenario's first car type).
    Returns:
        tuple of ``VTypeSpec``.
    """
    scenario_noise = car_follow_model is not None  # a scenario's drivers: its noise, not the fit's
    sumo_model = CALIBRATION_MODELS[model] if car_follow_model is None else car_follow_model
    out = []
    for m in members:
        p = m.params
        cf = {k: v for k, v in template.cf_params
              if k != "delta" and (k not in EIDM_NOISE_OFF or (scenario_noise and sumo_model == "EIDM"))}
        if sumo_model in IDM_FAMILY:
            cf["delta"] = p.delta
        if sumo_model == "EIDM" and not scenario_noise:  # as fitted: noise off
            cf.update(EIDM_NOISE_OFF)
        out.append(replace(
            template, id=m.id, probability=m.probability, car_follow_model=sumo_model,
            accel=p.accel, decel=p.decel, tau=p.tau,
            min_gap_m=p.minGap, max_speed_mps=p.maxSpeed, emergency_decel=p.emergencyDecel,
            sigma=0.0, speed_factor=1.0,
            speed_dev=0.0, cf_params=tuple(sorted(cf.items())),
        ))
    return tuple(out)
