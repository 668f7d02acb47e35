"""Outer optimisers over theta: the paper's fixed-length steps, L-BFGS, and concave Newton.

Each maximises ``f(theta) = L(theta) - l2/2 ||theta||^2`` given an ``evaluate(theta)`` that
returns an :class:`Evaluation` (L, its gradient and the Q table at theta). Traces record
``L`` (not the penalised ``f``) and theta after every outer iteration.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize as so

from irl.config import IRLConfig
from merge_irl.progress import progress_bar as _progress_bar


@dataclass(frozen=True)
class Evaluation:
    """``L``, ``dL/dtheta [K]`` and ``Q [S, A]`` at one theta; ``ok=False`` if Q failed."""

    loglik: float
    grad: np.ndarray
    q: np.ndarray
    ok: bool = True
    message: str = ""
    hess: np.ndarray | None = None  # [K, K] d2L/dtheta2 when available (Q-Avg)


@dataclass(frozen=True)
class AscentResult:
    """Where an outer optimiser stopped.

    Attributes:
        theta: ``[K]`` final weights; ``evaluation`` is at exactly this theta.
        loglik_trace: ``[n]``; theta_trace: ``[n, K]``.
        converged: the stopping rule was met (not a cap, not an inner failure).
        message: why it stopped.
        extra: optimiser scalars (iterations, evaluations, gradient norm).
    """

    theta: np.ndarray
    evaluation: Evaluation
    loglik_trace: np.ndarray
    theta_trace: np.ndarray
    converged: bool
    message: str
    extra: dict[str, float] = field(default_factory=dict)


def progress_bar(enabled: bool, total: int, desc: str) -> Any:
    """One fit's iterations when asked for (``merge-irl learn``): a bar on a terminal, progress
    lines on a log file or pipe (:mod:`merge_irl.progress`). Fits inside sweeps, trials and the
    demo are not asked: the work around them reports its own progress."""
    return _progress_bar(total, desc=desc, enabled=enabled, leave=False)


#: Features whose spread (:func:`feature_spread`) lies within these bounds are left unscaled by
#: :func:`preconditioner`: fits of features in ordinary units run exactly as before; one in units
#: a million times too small or large is searched, and started, at its own scale.
ORDINARY_SPREAD = (1e-3, 1e3)


def feature_spread(features: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``[K]`` the spread of each feature of ``features [S, A, K]`` across the actions of the
    visited states (``counts [S, A]`` steps): ``sqrt(sum_s n_s Var_a features[s, :, k] / sum_s
    n_s)``; 1 where a feature does not vary (or nothing is visited)."""
    n_s = counts.sum(axis=1)
    vis = n_s > 0
    if not vis.any():
        return np.ones(features.shape[2])
    b = features[vis]
    var = ((b - b.mean(axis=1, keepdims=True)) ** 2).mean(axis=1)  # [V, K]
    s = np.sqrt(n_s[vis] @ var / n_s[vis].sum())
    return np.where(np.isfinite(s) & (s > 0), s, 1.0)


def preconditioner(spread: np.ndarray) -> np.ndarray:
    """``[K]``: ``spread`` where it lies outside :data:`ORDINARY_SPREAD`, else 1."""
    lo, hi = ORDINARY_SPREAD
    return np.where((spread < lo) | (spread > hi), spread, 1.0)


def scaled_start(theta: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """A random start drawn in ordinary units, moved to each feature's own scale:
    ``theta / preconditioner(spread)`` (a weight of 0.3 on a feature of spread 1e14 starts the
    fit 1e13 nats from anything sensible)."""
    return np.asarray(theta, dtype=np.float64) / preconditioner(spread)


def penalised(ev: Evaluation, theta: np.ndarray, l2: float) -> tuple[float, np.ndarray]:
    """``(L - l2/2 |theta|^2, its gradient)``."""
    return ev.loglik - 0.5 * l2 * float(theta @ theta), ev.grad - l2 * theta


def unit_step_ascent(evaluate: Callable[[np.ndarray], Evaluation], theta0: np.ndarray,
                     config: IRLConfig, *, progress: bool = False, desc: str = "") -> AscentResult:
    """The paper's / reference code's outer loop.

    Repeat: evaluate ``L`` and ``g`` at theta; stop when ``|f_n - f_{n-1}| <= config.outer_tol``
    (``f`` the penalised objective, ``= L`` when ``l2 = 0``) or after ``config.max_outer``
    evaluations; else ``theta += step_size * g / ||g||``. Returns the last evaluated theta.
    """
    theta = np.asarray(theta0, dtype=np.float64).copy()
    lls, thetas = [], []
    prev_f = None
    converged, message = False, f"reached max_outer = {config.max_outer} outer steps"
    ev = None
    with progress_bar(progress, config.max_outer, desc) as bar:
        for n in range(config.max_outer):
            ev = evaluate(theta)
            lls.append(ev.loglik)
            thetas.append(theta.copy())
            bar.update(1)
            if not ev.ok:
                message = f"inner iteration failed at outer step {n + 1}: {ev.message}"
                break
            f, g = penalised(ev, theta, config.l2)
            if prev_f is not None and abs(f - prev_f) <= config.outer_tol:
                converged, message = True, f"|dL| <= {config.outer_tol:.3g} after {n + 1} outer steps"
                break
            norm = float(np.linalg.norm(g))
            if norm == 0.0:
                converged, message = True, f"zero gradient after {n + 1} outer steps"
                break
            prev_f = f
            if n + 1 < config.max_outer:
                theta = theta + config.step_size * g / norm
                if n % 64 == 0:
                    bar.set_postfix(L=f"{ev.loglik:.4f}")
    assert ev is not None, "IRLConfig validates max_outer >= 1, so the loop evaluated at least once"
    return AscentResult(theta, ev, np.array(lls), np.array(thetas).reshape(len(thetas), -1),
                        converged, message, {"outer_steps": float(len(lls))})


class _InnerFailure(Exception):
    pass


def lbfgs_ascent(evaluate: Callable[[np.ndarray], Evaluation], theta0: np.ndarray,
                 config: IRLConfig, *, progress: bool = False, desc: str = "",
                 gtol: float = 1e-7,
                 on_accept: Callable[[np.ndarray, Evaluation], None] | None = None,
                 scale: np.ndarray | None = None, reference: float = 1.0) -> AscentResult:
    """L-BFGS (scipy, ``L-BFGS-B`` without bounds) on ``-f``; stops at ``|grad f|_inf <= gtol``,
    a relative objective change below ``1e-13``, or ``config.max_outer`` iterations. An inner
    failure (``ok=False``) at the start aborts with ``converged=False``; at a line-search trial
    point it is a steep wall around the last accepted iterate. ``on_accept(theta, evaluation)`` is
    called at the start and after every accepted iterate (used to anchor warm starts).

    ``scale``: ``[K]`` positive; the search runs in ``u = scale * theta`` (diagonal
    preconditioning, as Q-Avg's Newton: :func:`preconditioner`); evaluations, traces and the
    returned theta stay in the original coordinates. ``converged`` needs the optimality check on
    the problem as given: the penalised gradient per unit of ``scale``, ``|g / scale|_inf``, at
    most ``max(100 gtol, 1e-5 max(1, min(|L|, reference)))``; ``reference``: the size of ``L``
    at a sane point (e.g. ``|L(0)|``), so that an absurd ``L`` does not loosen the check.
    """
    sc = np.ones(np.size(theta0)) if scale is None else np.asarray(scale, dtype=np.float64)
    theta = np.asarray(theta0, dtype=np.float64).copy()
    bar = progress_bar(progress, config.max_outer, desc)
    problem = _LbfgsProblem(evaluate, config.l2, sc, on_accept, bar)
    problem.remember(theta, problem.ev_at(theta))
    try:
        res = so.minimize(problem.fun, theta * sc, jac=True, method="L-BFGS-B", callback=problem.callback,
                          options={"maxiter": config.max_outer, "gtol": gtol, "ftol": 1e-13,
                                   "maxcor": 20, "maxls": 50})
    except _InnerFailure as e:
        bar.close()
        x, ev = problem.last
        problem.lls.append(ev.loglik)
        problem.thetas.append(x)
        return AscentResult(x, ev, np.array(problem.lls), np.array(problem.thetas), False,
                            f"inner fixed point failed: {e}", {"outer_steps": float(len(problem.lls))})
    bar.close()
    return _lbfgs_result(problem, res, l2=config.l2, gtol=gtol, scaled=scale is not None,
                         reference=reference)


class _LbfgsProblem:
    """The objective :func:`lbfgs_ascent` hands scipy, in ``u = sc * theta`` (``sc``: ``[K]``).

    Holds the evaluation cache (by theta's bytes, cleared past 8 entries), the last evaluated
    ``[theta, evaluation]`` (``last``), the inner-failure messages of trial points
    (``failures``), the anchor ``[x, -f, -g]`` of the last accepted iterate and the trace of
    accepted iterates (``lls``: log-likelihoods; ``thetas``: ``[K]`` arrays).
    """

    def __init__(self, evaluate: Callable[[np.ndarray], Evaluation], l2: float, sc: np.ndarray,
                 on_accept: Callable[[np.ndarray, Evaluation], None] | None, bar) -> None:
        self.evaluate, self.l2, self.sc, self.on_accept, self.bar = evaluate, l2, sc, on_accept, bar
        self.cache: dict[bytes, Evaluation] = {}
        self.last: list = []
        self.failures: list[str] = []
        self.anchor: list = []  # [x, -f, -g] of the last accepted iterate
        self.lls: list = []
        self.thetas: list = []

    def ev_at(self, x: np.ndarray) -> Evaluation:
        """The evaluation at theta ``x`` (``[K]``), cached."""
        key = x.tobytes()
        if key not in self.cache:
            if len(self.cache) > 8:
                self.cache.clear()
            self.cache[key] = self.evaluate(x.copy())
        return self.cache[key]

    def fun(self, u: np.ndarray) -> tuple[float, np.ndarray]:
        """``(-f, -grad f / sc)`` at ``u`` (``[K]``); a steep wall where the inner solve fails.

        Raises:
            _InnerFailure: the inner solve fails before any iterate is accepted.
        """
        sc = self.sc
        x = u / sc  # theta
        ev = self.ev_at(x)
        self.last[:] = [x.copy(), ev]
        if not ev.ok:
            if not self.anchor:
                raise _InnerFailure(ev.message)
            # a trial point without a fixed point: a steep wall around the last accepted
            # iterate sends the line search back
            self.failures.append(ev.message)
            xa, fa, ga = self.anchor
            d = u - xa * sc
            wall = 1e3 * (1.0 + abs(fa))
            return fa + wall * (1.0 + float(d @ d)), 2.0 * wall * d
        f, g = penalised(ev, x, self.l2)
        return -f, -g / sc

    def remember(self, x: np.ndarray, ev: Evaluation) -> None:
        """Anchor the accepted iterate ``x`` (theta, ``[K]``) and call ``on_accept``."""
        if ev.ok:
            f, g = penalised(ev, x, self.l2)
            self.anchor[:] = [np.array(x, dtype=float), -f, -g]
        if self.on_accept is not None:
            self.on_accept(np.asarray(x), ev)

    def callback(self, u: np.ndarray) -> None:
        """scipy's per-iteration callback: remember, trace and report the iterate ``u``."""
        x = np.asarray(u) / self.sc
        ev = self.ev_at(x)
        self.remember(x, ev)
        self.lls.append(ev.loglik)
        self.thetas.append(np.array(x, dtype=float))
        self.bar.update(1)
        self.bar.set_postfix(L=f"{ev.loglik:.4f}")


def _lbfgs_result(problem: _LbfgsProblem, res, *, l2: float, gtol: float, scaled: bool,
                  reference: float) -> AscentResult:
    """The :class:`AscentResult` of a finished scipy run ``res``: the optimality check and message.

    ``converged`` needs scipy's success and ``|g / sc|_inf`` (penalised gradient per unit of
    scale) at most ``max(100 gtol, 1e-5 max(1, min(|L|, |reference|)))``; ``scaled``: a
    ``scale`` was given (the message then also reports the scaled norm).
    """
    sc, lls, thetas = problem.sc, problem.lls, problem.thetas
    x = np.asarray(res.x, dtype=float) / sc
    ev = problem.ev_at(x)
    if not thetas or not np.array_equal(thetas[-1], x):
        lls.append(ev.loglik)
        thetas.append(x.copy())
    g_pen = penalised(ev, x, l2)[1]
    gnorm = float(np.max(np.abs(g_pen)))
    g_scaled = float(np.max(np.abs(g_pen / sc)))
    tol = max(gtol * 100, 1e-5 * max(1.0, min(abs(ev.loglik), abs(reference))))
    ok = bool(res.success) and g_scaled <= tol
    msg = f"L-BFGS: {res.message} after {res.nit} iterations, |grad|_inf = {gnorm:.3g}"
    if scaled:
        msg += f" ({g_scaled:.3g} per unit of feature spread)"
    if res.success and not ok:
        msg += f", above {tol:.3g}: not an optimum"
    if problem.failures:
        msg += (f"; {len(problem.failures)} trial points had no fixed point and were stepped back from "
                f"(first: {problem.failures[0]})")
    return AscentResult(x, ev, np.array(lls), np.array(thetas).reshape(len(thetas), -1), ok, msg,
                        {"outer_steps": float(res.nit), "evaluations": float(res.nfev),
                         "grad_inf": gnorm, "grad_inf_scaled": g_scaled})


def newton_concave(evaluate: Callable[[np.ndarray], Evaluation], theta0: np.ndarray,
                   config: IRLConfig, *, progress: bool = False, desc: str = "",
                   max_iter: int = 500, theta_cap: float = 1e8, ftol: float = 0.0,
                   scale: np.ndarray | None = None) -> AscentResult:
    """Damped Newton for a concave ``f`` whose evaluation carries the Hessian of ``L``.

    Step ``p = (-H_f)^+ g`` on the eigenvectors of ``-H_f`` (eigenvalues floored at
    ``1e-12 * max eigenvalue``, so flat directions with a non-zero gradient, the signature of
    unbounded weights, get long steps, capped at ``10 (1 + |theta|)``), then backtracking until
    the Armijo condition holds.

    ``scale``: ``[K]`` positive; the step is taken in the coordinates ``u = scale * theta``
    (diagonal preconditioning: ``H_u = H / (scale scale^T)``, ``g_u = g / scale``), so that
    the eigenvalue floor and the step cap do not depend on the units of the features
    (:func:`irl.methods.qavg.feature_scale`). Evaluations, traces and ``theta`` stay in the
    original coordinates. None: no scaling.
    Stops when the Newton decrement ``g.p`` is below ``1e-14 max(1, |f|)`` (the global
    maximum to that precision, or the supremum when weights diverge), ``max|scale theta|`` exceeds
    ``theta_cap``, when an accepted step gains less than ``ftol max(1, |f|)`` (use a positive
    ``ftol`` when the weights are known to diverge, where the gains only shrink geometrically),
    or after ``min(max_iter, config.max_outer)`` iterations.

    Raises:
        ValueError: ``evaluate`` returned an :class:`Evaluation` without ``hess``.
    """
    theta = np.asarray(theta0, dtype=np.float64).copy()
    l2 = config.l2
    ev = evaluate(theta)
    f, g = penalised(ev, theta, l2)
    lls, thetas = [ev.loglik], [theta.copy()]
    n_iter = min(max_iter, config.max_outer)
    sc = np.ones(theta.size) if scale is None else np.asarray(scale, dtype=np.float64)
    if sc.shape != theta.shape or not np.all(np.isfinite(sc) & (sc > 0)):
        raise ValueError(f"newton_concave: scale must be {theta.size} finite positive numbers, got {sc}")
    converged, message = False, f"Newton: reached {n_iter} iterations"
    with progress_bar(progress, n_iter, desc) as bar:
        for it in range(n_iter):
            if ev.hess is None:
                raise ValueError("newton_concave: evaluate returned no Hessian (Evaluation.hess is None)")
            h = -(ev.hess - l2 * np.eye(theta.size)) / np.outer(sc, sc)  # PSD, in u = sc * theta
            lam, vec = np.linalg.eigh(0.5 * (h + h.T))
            radius = 10.0 * (1.0 + float(np.linalg.norm(sc * theta)))  # |u| grows at most 11x a step
            lam_floor = max(float(lam.max(initial=0.0)) * 1e-12, 1e-300)
            with np.errstate(over="ignore"):
                coef = (vec.T @ (g / sc)) / np.maximum(lam, lam_floor)
            p = vec @ np.clip(coef, -radius, radius)
            p_norm = float(np.linalg.norm(p))
            if p_norm > radius:
                p = p * (radius / p_norm)
            p = p / sc  # back to theta
            decrement = float(g @ p)
            if not np.all(np.isfinite(p)) or decrement <= 1e-14 * max(1.0, abs(f)):
                converged, message = True, f"Newton: optimum reached after {it} iterations"
                break
            t, accepted = 1.0, False
            for _ in range(80):
                cand = theta + t * p
                ev_c = evaluate(cand)
                f_c, g_c = penalised(ev_c, cand, l2)
                if np.isfinite(f_c) and f_c >= f + 1e-4 * t * decrement:
                    accepted = True
                    break
                t *= 0.5
            if not accepted:
                converged, message = True, f"Newton: no further ascent possible after {it} iterations"
                break
            gain = f_c - f
            theta, ev, f, g = cand, ev_c, f_c, g_c
            lls.append(ev.loglik)
            thetas.append(theta.copy())
            bar.update(1)
            if float(np.max(np.abs(sc * theta))) > theta_cap:
                converged, message = True, f"Newton: |theta| passed {theta_cap:.0e} (weights diverge)"
                break
            if gain < ftol * max(1.0, abs(f)):
                converged, message = True, f"Newton: gains below {ftol:.0e} relative after {it + 1} iterations"
                break
            stop = stalled(lls, thetas)
            if stop is not None:
                converged, message = False, f"Newton: {stop}"
                break
    gnorm = float(np.max(np.abs(g)))
    extra = {"outer_steps": float(len(lls) - 1), "grad_inf": gnorm}
    if not converged and "weights diverge" in message:
        extra["diverged"] = 1.0
    return AscentResult(theta, ev, np.array(lls), np.array(thetas).reshape(len(thetas), -1),
                        converged, message, extra)


#: :func:`stalled`: accepted steps looked back over, the gain over them (relative to ``max(1, |L|)``)
#: below which L counts as no longer rising, and how far ``|theta|`` must have run from its start
#: (``|theta| > STALL_THETA_RUN (1 + |theta_0|)``) or grown over the window (``STALL_THETA_GROWTH`` times)
#: for the stop to be called diverging weights rather than a stall.
STALL_WINDOW = 5
STALL_GAIN = 1e-12
STALL_THETA_RUN = 1e6
STALL_THETA_GROWTH = 2.0


def stalled(lls: list[float], thetas: list[np.ndarray]) -> str | None:
    """Why an ascent should stop although its rule is not met, or None: over the last
    :data:`STALL_WINDOW` accepted steps L rose by less than :data:`STALL_GAIN` ``max(1, |L|)``
    (rounding-level gains: the line search accepts steps that change nothing). Then, if
    ``|theta|`` grew geometrically over the window or ran far from its start, the weights diverge
    (the likelihood approaches a supremum at infinite weights: a separable or nearly separable
    problem); else the ascent has stalled.

    Args:
        lls: L after each step (the start first); thetas: ``[K]`` weights after each step.
    """
    if len(lls) <= STALL_WINDOW:
        return None
    gain = lls[-1] - lls[-1 - STALL_WINDOW]
    if gain > STALL_GAIN * max(1.0, abs(lls[-1])):
        return None
    n_now, n_then, n_0 = (float(np.linalg.norm(thetas[i])) for i in (-1, -1 - STALL_WINDOW, 0))
    steps = len(lls) - 1
    if n_now > STALL_THETA_RUN * (1.0 + n_0) or n_now > STALL_THETA_GROWTH * max(n_then, 1e-300):
        return (f"weights diverge: L rose by {gain:.3g} over the last {STALL_WINDOW} of {steps} iterations while "
                f"|theta| reached {n_now:.3g} (from {n_0:.3g}); the likelihood approaches its supremum at "
                "infinite weights")
    return f"stalled: L rose by {gain:.3g} over the last {STALL_WINDOW} of {steps} iterations"



def recession_direction(diffs: np.ndarray, rel_tol: float = 1e-9) -> np.ndarray | None:
    """A direction along which the multinomial-logit likelihood never decreases and somewhere rises.

    ``diffs [m, K]`` holds ``D(s, a_obs) - D(s, b)`` for every observed (s, a_obs) and every other
    action b. The likelihood is unbounded above (no finite maximiser) iff some ``d`` has
    ``diffs @ d >= 0`` everywhere and ``> 0`` somewhere. Solved as the LP
    ``max sum(diffs @ d)  s.t.  diffs @ d >= 0, -1 <= d <= 1``. Returns ``d`` or None.
    """
    if diffs.size == 0:
        return None
    scale = float(np.max(np.abs(diffs)))
    if scale == 0.0:
        return None
    a = diffs / scale
    k = a.shape[1]
    res = so.linprog(-a.sum(axis=0), A_ub=-a, b_ub=np.zeros(a.shape[0]),
                     bounds=[(-1.0, 1.0)] * k, method="highs")
    if res.status != 0:
        return None
    d = np.asarray(res.x)
    gain = a @ d
    if float(gain.max(initial=0.0)) > rel_tol * k and float(gain.min(initial=0.0)) >= -rel_tol * k:
        return d
    return None
