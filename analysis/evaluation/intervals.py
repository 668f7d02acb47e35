"""95 % intervals of the evaluation's rates: :func:`rate_ci95` (a share, Wilson score) and
:func:`poisson_rate_ci95` (events per unit, exact Poisson)."""

from __future__ import annotations

from scipy.stats import binomtest, chi2


def rate_ci95(k: int, n: int) -> tuple[float, float, float]:
    """``(k / n, low, high)``: a rate with its Wilson score 95 % interval (NaN when ``n == 0``)."""
    if n <= 0:
        return float("nan"), float("nan"), float("nan")
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=0.95, method="wilson")
    return k / n, float(ci.low), float(ci.high)


def poisson_rate_ci95(k: int, n: int) -> tuple[float, float, float]:
    """``(k / n, low, high)``: ``k`` events over ``n`` units (e.g. emergency brakings per controlled
    A) with the exact (Garwood) Poisson 95 % interval of the count, divided by ``n``: ``low =
    chi2.ppf(0.025, 2k) / 2n`` (0 when ``k = 0``), ``high = chi2.ppf(0.975, 2k + 2) / 2n``. It
    assumes independent events and is too narrow when they cluster. NaNs when ``n <= 0``.

    Raises:
        ValueError: ``k < 0``.
    """
    if k < 0:
        raise ValueError(f"poisson_rate_ci95: negative count {k}")
    if n <= 0:
        return float("nan"), float("nan"), float("nan")
    lo = 0.0 if k == 0 else float(chi2.ppf(0.025, 2 * k)) / 2
    hi = float(chi2.ppf(0.975, 2 * k + 2)) / 2
    return k / n, lo / n, hi / n
