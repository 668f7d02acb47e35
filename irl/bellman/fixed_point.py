"""Exact fixed points of the Boltzmann backup ``Q = R + gamma P V_beta(Q)`` (Q-SM, MLIRL).

Newton's method with a backtracking line search on the residual ``F(q) = q - r - gamma P V(q)``
(the backup's linear algebra is :mod:`irl.bellman.operators`), Newton by continuation in beta, and the
damped iteration of the paper's Eq. 15.

The Boltzmann backup is not a non-expansion. A fixed point always exists (``V`` lies between
the smallest and largest ``Q(s', .)``, so the backup maps a bounded box into itself), but it may
not be unique and may repel the damped iteration of the paper's Eq. 15. :func:`boltzmann_fixed_point`
reports failure (iteration cap, stagnating residual, non-finite values, singular Jacobian) and
:func:`~irl.bellman.stability.iteration_stability` tells whether the damped iteration could
converge to the point found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from irl.bellman.operators import _soft_mean, solve_backup_system
from irl.bellman.stability import _stability
from irl.transitions import SuccessorModel


@dataclass(frozen=True)
class FixedPoint:
    """Outcome of :func:`boltzmann_fixed_point`.

    Attributes:
        q: ``[S, A]`` the last iterate (the fixed point when ``converged``).
        converged: residual below tolerance with finite values.
        iterations: Newton / fallback iterations used.
        residual: final ``max |F(q)|``.
        message: why it stopped.
    """

    q: np.ndarray
    converged: bool
    iterations: int
    residual: float
    message: str


def _residual(q_flat, r_flat, succ, beta, gamma, with_c=True):
    """``(F(q) [S*A], c [S, A] or None)``."""
    S, A = succ.n_states, succ.n_actions
    v, _, ct = _soft_mean(q_flat.reshape(S, A).T, beta, with_c)
    f = q_flat - r_flat
    f -= gamma * (succ.p @ v)
    return f, (None if ct is None else ct.T)


def fixed_point_tolerance(r: np.ndarray, gamma: float) -> float:
    """Absolute residual tolerance of the exact solver: ``1e-13`` of the Q scale ``max|R|/(1-gamma)``.

    This is the target. With large features or theta, round-off alone can leave residuals of
    ~1e-12 of the scale, so a solve that stalls within ``ROUNDOFF_SLACK`` times this target is
    accepted as converged (see ``_at_roundoff_floor``).
    """
    scale = max(1.0, float(np.max(np.abs(r))) / (1.0 - gamma))
    return 1e-13 * scale


#: A stalled solve whose residual is within this factor of the tolerance is at the round-off floor.
ROUNDOFF_SLACK = 1e3


def _at_roundoff_floor(res: float, tol: float) -> bool:
    return bool(np.isfinite(res) and res <= ROUNDOFF_SLACK * tol)


def _newton(r_flat, succ, beta, gamma, q, max_iter, tol) -> FixedPoint:
    """Plain Newton with Armijo backtracking on ``|F|^2``; gives up when a step makes no headway
    or 10 iterations pass without halving the best residual."""
    S, A = succ.n_states, succ.n_actions
    f, c = _residual(q, r_flat, succ, beta, gamma)
    res, merit = float(np.max(np.abs(f))), float(f @ f)
    best, since = res, 0
    for it in range(1, max_iter + 1):
        if not np.isfinite(res):
            return FixedPoint(q.reshape(S, A), False, it - 1, res, "non-finite Q values")
        if res <= tol:
            return FixedPoint(q.reshape(S, A), True, it - 1, res, "converged")
        try:
            step = solve_backup_system(succ, c.reshape(S, A), gamma, -f)
        except RuntimeError:
            return FixedPoint(q.reshape(S, A), False, it, res, "singular Jacobian (I - gamma P J)")
        if not np.all(np.isfinite(step)):
            return FixedPoint(q.reshape(S, A), False, it, res, "Newton step not finite")
        t = 1.0
        for _ in range(20):  # Armijo on the merit |F|^2 (Newton's step is a descent direction)
            q_try = q + t * step
            f_try, c_try = _residual(q_try, r_flat, succ, beta, gamma)
            merit_try = float(f_try @ f_try)
            if np.isfinite(merit_try) and merit_try <= (1.0 - 1e-4 * t) * merit:
                break
            t *= 0.5
        else:
            if _at_roundoff_floor(res, tol):
                return FixedPoint(q.reshape(S, A), True, it, res, "converged (round-off floor)")
            return FixedPoint(q.reshape(S, A), False, it, res, f"Newton stalls at residual {res:.3g}")
        q, f, c, merit = q_try, f_try, c_try, merit_try
        res = float(np.max(np.abs(f)))
        if res < 0.5 * best:
            best, since = res, 0
        else:
            since += 1
            if since >= 10:
                if _at_roundoff_floor(res, tol):
                    return FixedPoint(q.reshape(S, A), True, it, res, "converged (round-off floor)")
                return FixedPoint(q.reshape(S, A), False, it, res,
                                  f"Newton stagnates at residual {res:.3g}")
    ok = bool(np.isfinite(res) and res <= tol)
    return FixedPoint(q.reshape(S, A), ok, max_iter, res,
                      "converged" if ok else f"Newton: residual {res:.3g} after {max_iter} iterations")


def _damped_backups(r_flat, succ, beta, gamma, q, max_backups, settle):
    """Damped backups ``q <- q - omega F(q)`` (the Eq. 15 iteration, synchronous) until
    ``max|F| < settle`` or ``max_backups``. ``omega`` starts at 1/2 and halves (down to 1/16)
    whenever 500 backups end with a larger residual than they started with.
    Returns ``(q, backups used, settled)``."""
    omega, used = 0.5, 0
    f, _ = _residual(q, r_flat, succ, beta, gamma, with_c=False)
    res = float(np.abs(f).max())
    window_start = res
    while used < max_backups:
        q = q - omega * f
        f, _ = _residual(q, r_flat, succ, beta, gamma, with_c=False)
        used += 1
        res = float(np.abs(f).max())
        if not np.isfinite(res):
            return q, used, False
        if res < settle:
            return q, used, True
        if used % 500 == 0:
            if res >= window_start and omega > 1.0 / 16:
                omega *= 0.5
            window_start = res
    return q, used, False


def _continuation(r_flat, succ, beta, gamma, scale, max_iter, tol) -> FixedPoint | None:
    """Newton along ``beta_0 < 2 beta_0 < ... < beta``, each stage warm-started by the last.

    At ``beta_0 * scale <= 0.1`` the backup is nearly the (linear) average and Newton converges
    from ``R`` at once; doubling beta keeps each start close to its solution. None when
    ``beta`` is already that small (plain Newton has then just failed for another reason).
    """
    betas = [beta]
    while betas[-1] * scale > 0.1 and len(betas) < 60:
        betas.append(betas[-1] / 2.0)
    if len(betas) == 1:
        return None
    q, total = r_flat.copy(), 0
    for b in reversed(betas):
        fp = _newton(r_flat, succ, b, gamma, q, max_iter, tol)
        total += fp.iterations
        if not fp.converged:
            return FixedPoint(fp.q, False, total, fp.residual,
                              f"continuation failed at beta {b:.3g}: {fp.message}")
        q = fp.q.ravel().copy()
    return FixedPoint(fp.q, True, total, fp.residual, "converged")


def boltzmann_fixed_point(
    r: np.ndarray,
    succ: SuccessorModel,
    beta: float,
    gamma: float,
    *,
    q0: np.ndarray | None = None,
    max_iter: int = 200,
    max_backups: int = 20000,
    tol: float | None = None,
    attracting: bool = True,
    fallback: bool = True,
    newton: FixedPoint | None = None,
) -> FixedPoint:
    """Solve ``Q = R + gamma P V_beta(Q)``.

    Args:
        r: ``[S, A]`` rewards ``phi @ theta``.
        succ: successor model (terminal pairs get ``Q = R``).
        q0: ``[S, A]`` warm start (default: ``r``).
        max_iter: cap on Newton iterations (per Newton run).
        max_backups: cap on damped backups.
        tol: absolute tolerance on ``max |F(q)|`` (default :func:`fixed_point_tolerance`).
        fallback: when Newton from the start fails, try continuation and damped backups
            (False: report Newton's failure at once).
        attracting: only accept a fixed point that attracts the damped iteration of Eq. 15
            (:func:`~irl.bellman.stability.iteration_stability`). The Boltzmann backup can have several fixed points
            and Newton alone may land on a repelling one.
        newton: the result of the first step, Newton from ``q0`` with these ``max_iter`` and
            ``tol``, when the caller has it already (it is deterministic: passing it skips
            recomputing it and changes nothing else).

    Strategy: Newton (``(I - gamma P J) step = -F``, Armijo backtracking on ``|F|_2^2``) from the
    start. If it fails, or (with ``attracting``) lands on a repelling point: Newton by
    continuation in beta (from a beta small enough for the backup to be nearly linear, doubling
    up to ``beta``, each stage warm-started by the previous one). If that fails too, damped backups
    ``q <- q - omega F(q)`` run from the start (this is the Eq. 15 iteration, so it follows the
    paper's path toward an attracting point; ``omega`` halves while the residual does not drop)
    until ``max|F|`` is below ``1e-4`` of the Q scale, then Newton polishes (if Newton still
    stalls, the backups continue to ``1e-8`` of the scale, then to ``tol``). ``converged`` is
    False (with the reason in ``message``) on non-finite values, when the damped backups
    oscillate at every damping, when only repelling points are found, or at the caps.
    """
    r_flat = np.asarray(r, dtype=np.float64).ravel()
    tol = fixed_point_tolerance(r, gamma) if tol is None else tol
    start = (r_flat.copy() if q0 is None else np.asarray(q0, dtype=np.float64).ravel().copy())
    fp = newton if newton is not None else _newton(r_flat, succ, beta, gamma, start.copy(), max_iter, tol)
    iterations = fp.iterations
    lam = float("nan")
    if fp.converged:
        if not attracting:
            return fp
        stable, lam, _ = _stability(fp.q, succ, beta, gamma)
        if stable is not False:
            return fp
    if not fallback:
        if fp.converged:
            return FixedPoint(fp.q, False, iterations, fp.residual,
                              f"Newton found a repelling fixed point (eigenvalue real part {lam:.4g})")
        return fp
    scale = max(1.0, float(np.max(np.abs(r_flat))) / (1.0 - gamma))
    cont = _continuation(r_flat, succ, beta, gamma, scale, max_iter, tol)
    if cont is not None:
        iterations += cont.iterations
        if cont.converged:
            stable, lam, _ = _stability(cont.q, succ, beta, gamma) if attracting else (True, 0, 0)
            if stable is not False:
                return FixedPoint(cont.q, True, iterations, cont.residual, "converged")
    run = _backups_then_newton(r_flat, succ, beta, gamma, start, scale, tol, max_backups, max_iter)
    iterations += run.iterations
    if run.stuck:
        newton = run.newton or fp  # the last Newton attempt before the backups stopped
        why = "found only a repelling point" if newton.converged else "failed: " + newton.message
        return FixedPoint(run.fp.q, False, iterations, run.fp.residual,
                          f"the damped backup does not settle (residual {run.fp.residual:.3g} after "
                          f"{run.backups} backups) and Newton {why}")
    fp = run.fp
    if not fp.converged:
        return FixedPoint(fp.q, False, iterations, fp.residual, f"Newton after damped backups: {fp.message}")
    if attracting:
        stable, lam, _ = _stability(fp.q, succ, beta, gamma)
        if stable is False:
            return FixedPoint(fp.q, False, iterations, fp.residual,
                              f"only fixed points that repel the damped iteration were found "
                              f"(backup Jacobian eigenvalue real part {lam:.4g} >= 1)")
    return FixedPoint(fp.q, True, iterations, fp.residual, "converged")


def iteration_fixed_point(
    r: np.ndarray,
    succ: SuccessorModel,
    beta: float,
    gamma: float,
    *,
    max_iter: int = 200,
    max_backups: int = 20000,
    tol: float | None = None,
) -> FixedPoint:
    """The fixed point of ``Q = R + gamma P V_beta(Q)`` that the damped iteration of the paper's
    Eq. 15 reaches from ``Q = 0`` (the paper's algorithm; the Boltzmann backup may have several).

    Damped synchronous backups ``q <- q - omega F(q)`` (:func:`boltzmann_fixed_point`'s fallback,
    ``omega`` from 1/2) run from zero until ``max|F|`` is below ``1e-4`` of the Q scale
    ``max|R|/(1-gamma)``; Newton then polishes the point the iteration is settling on (if Newton
    stalls, the backups continue to ``1e-8`` of the scale, then to ``tol``). ``r`` is ``[S, A]``;
    ``converged`` is False when the backups do not settle within ``max_backups`` (they cycle, or
    diverge) or Newton fails. Deterministic: no warm start, so the answer depends on theta alone.
    """
    r_flat = np.asarray(r, dtype=np.float64).ravel()
    tol = fixed_point_tolerance(r, gamma) if tol is None else tol
    scale = max(1.0, float(np.max(np.abs(r_flat))) / (1.0 - gamma))
    run = _backups_then_newton(r_flat, succ, beta, gamma, np.zeros_like(r_flat), scale, tol, max_backups, max_iter)
    fp = run.fp
    if run.stuck:
        return FixedPoint(fp.q, False, run.iterations, fp.residual,
                          f"the Eq. 15 iteration from Q = 0 does not settle (residual {fp.residual:.3g} after "
                          f"{run.backups} damped backups)")
    if fp.converged:
        return FixedPoint(fp.q, True, run.iterations, fp.residual, fp.message if run.at_floor else "converged")
    return FixedPoint(fp.q, False, run.iterations, fp.residual, f"Newton after damped backups: {fp.message}")


@dataclass(frozen=True)
class _BackupRun:
    """What :func:`_backups_then_newton` reached.

    Attributes:
        fp: the last Newton result; or, when the backups stopped (``stuck``) or settled only to
            the round-off floor (``at_floor``), the backups' own point ``[S, A]`` and residual.
        iterations: damped backups plus Newton iterations.
        backups: damped backups alone.
        stuck: the backups stopped before settling (cycling, diverging, or the cap).
        at_floor: the last pass settled only to the round-off floor of ``tol`` (``fp`` converged).
        newton: the last Newton result (None when the first backup pass already stopped).
    """

    fp: FixedPoint
    iterations: int
    backups: int
    stuck: bool = False
    at_floor: bool = False
    newton: FixedPoint | None = None


def _backups_then_newton(r_flat: np.ndarray, succ: SuccessorModel, beta: float, gamma: float, q: np.ndarray,
                         scale: float, tol: float, max_backups: int, max_iter: int) -> _BackupRun:
    """Damped backups (the Eq. 15 iteration) from ``q [S*A]`` until ``max|F|`` is below ``1e-4``
    of ``scale``, then Newton; while Newton fails, backups to ``1e-8`` of ``scale`` and to
    ``tol`` with Newton after each pass. Shared by :func:`boltzmann_fixed_point`'s fallback and
    :func:`iteration_fixed_point`."""
    S, A = succ.n_states, succ.n_actions
    total, newton_its = 0, 0
    fp: FixedPoint | None = None
    for settle in (1e-4 * scale, 1e-8 * scale, tol):
        q, used, settled = _damped_backups(r_flat, succ, beta, gamma, q, max_backups - total, settle)
        total += used
        if not settled:
            f, _ = _residual(q, r_flat, succ, beta, gamma)
            res = float(np.max(np.abs(f)))
            floor = settle == tol and _at_roundoff_floor(res, tol)
            point = FixedPoint(q.reshape(S, A), floor, total, res,
                               "converged (round-off floor)" if floor else "the damped backups do not settle")
            return _BackupRun(point, newton_its + total, total, stuck=not floor, at_floor=floor, newton=fp)
        fp = _newton(r_flat, succ, beta, gamma, q, max_iter, tol)
        newton_its += fp.iterations
        if fp.converged:
            break
    assert fp is not None, "each of the three passes returns or runs Newton"
    return _BackupRun(fp, newton_its + total, total, newton=fp)
