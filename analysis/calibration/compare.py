"""The calibration check's comparison of simulated and real states, per variable (the two-sample
Kolmogorov-Smirnov statistic and the Jensen-Shannon divergence of histograms on common bins:
:func:`compare_distributions`), and why a variable misses the KS target (:func:`diagnose`;
docs/calibration.md, *Which variable misses and why*)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.calibration.states import VARIABLES

HIST_BINS = 40
#: The calibration target: KS distance at most this for each variable.
KS_TARGET = 0.15


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
