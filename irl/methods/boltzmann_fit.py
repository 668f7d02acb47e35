"""Likelihood fits whose Q is a Boltzmann-backup fixed point: shared by Q-SM and MLIRL.

Q-SM and MLIRL solve the same equation ``Q = R + gamma P (sum_b pi(b|s') Q(s', b))`` and differ
only in ``P`` (a :class:`~irl.transitions.SuccessorModel`): the demonstrations' observed
successors with terminal pairs (Q-SM), or a full transition model without any (MLIRL).

* :class:`ExactBoltzmann` solves the fixed point by Newton (:func:`irl.bellman.fixed_point.boltzmann_fixed_point`,
  warm-started from the previous outer step), differentiates it implicitly, and
  :func:`fit_exact` runs L-BFGS on ``-L``. After the fit it checks whether the damped iteration
  of Eq. 15 could converge to the fixed point found (:func:`irl.bellman.stability.iteration_stability`);
  if not, the result says so and ``converged`` is False.
* :class:`DampedBoltzmann` is the synchronous damped backup over all pairs
  (``Q <- (1-alpha) Q + alpha (R + gamma P V(Q))`` and the same for dQ), used by MLIRL's
  faithful solver (the Babes-Vroman iteration).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from irl.ascent import Evaluation, feature_spread, lbfgs_ascent, preconditioner
from irl.bellman.fixed_point import FixedPoint, boltzmann_fixed_point, iteration_fixed_point
from irl.bellman.operators import backup_operator, boltzmann_dq, mean_weights
from irl.bellman.stability import iteration_stability
from irl.boltzmann import demo_counts, loglik_from_counts, loglik_grad_from_counts
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.methods.common import result_from_ascent
from irl.methods.faithful import FaithfulSolver
from irl.result import FitResult
from irl.transitions import SuccessorModel, reachable_states, restrict
from irl.unbounded import boltzmann_recession

#: Newton iterations allowed per fixed point (``config.max_inner`` caps it further).
NEWTON_CAP = 200
#: Damped backups allowed when a line-search trial point leaves the anchor's branch.
JUMP_BACKUPS = 2000


class ExactBoltzmann:
    """``evaluate(theta)``: exact fixed point, ``L`` and ``dL/dtheta`` by implicit differentiation.

    The fixed point is solved only on the states reachable from the demonstrated ones
    (:func:`irl.transitions.reachable_states`): ``L`` depends on nothing else.

    Warm starts: the Boltzmann backup can have several fixed points, so which one Newton finds
    depends on where it starts. Every evaluation starts from the fixed point of the *anchor*,
    the last accepted outer iterate (:meth:`accept`), never from a line-search trial point; so
    within one line search ``L`` is one smooth function of theta (the branch continued from the
    anchor), and the result depends only on the seed. Without an anchor, Newton starts from
    ``Q = R``. :meth:`full_q` extends the solution to all states.

    With ``from_zero`` (Q-SM) the first evaluation (no anchor) takes the fixed point that the
    damped Eq. 15 iteration reaches from ``Q = 0`` (:func:`irl.bellman.fixed_point.iteration_fixed_point`),
    the paper's algorithm's answer; :func:`fit_exact` checks the final one the same way.
    """

    def __init__(self, demos: Demonstrations, succ: SuccessorModel, config: IRLConfig,
                 from_zero: bool = False):
        self.from_zero = from_zero
        self.branch_loglik: float | None = None  # set when the final branch is not the one from Q = 0
        states, _, _ = demos.flat()
        self.full_succ = succ
        self.full_features = demos.features
        self.closure = reachable_states(succ, states)
        self.succ = restrict(succ, self.closure)
        self.features = demos.features[self.closure]
        self.counts = demo_counts(demos)[self.closure]
        self.config = config
        self.newton_iterations = 0
        self.branch_jumps = 0
        self.anchor: tuple[np.ndarray, np.ndarray] | None = None  # (theta, q)

    def accept(self, theta: np.ndarray, ev: Evaluation) -> None:
        """Make ``theta`` (with its evaluation) the warm start of the following evaluations."""
        if ev.ok:
            self.anchor = (np.array(theta, dtype=np.float64), ev.q)

    def solve(self, theta: np.ndarray):
        """The fixed point on the reachable states (:func:`boltzmann_fixed_point`, Newton capped
        at ``min(200, max_inner)`` iterations, damped backups at ``max_inner``), from the anchor;
        if that fails, Newton along the segment anchor -> theta in halving steps; if the
        anchor's branch ends before theta (a fold): every fallback of
        :func:`boltzmann_fixed_point` from the anchor's Q, with at most ``JUMP_BACKUPS`` damped
        backups. Without an anchor (the first evaluation): from ``R``, with every fallback."""
        c = self.config

        def at(th, q0, fallback=True, backups=c.max_inner, newton=None):
            # continuing an attracting anchor's branch: stability only changes where Newton
            # meets a singular Jacobian, so the eigenvalue check is left to cold starts
            fp = boltzmann_fixed_point(self.features @ th, self.succ, c.beta, c.gamma, q0=q0,
                                       fallback=fallback, attracting=q0 is None, newton=newton,
                                       max_iter=min(NEWTON_CAP, c.max_inner), max_backups=backups)
            self.newton_iterations += fp.iterations - (0 if newton is None else newton.iterations)
            return fp

        if self.anchor is None:
            if self.from_zero:
                return self.from_zero_point(theta)
            return at(theta, None)
        th0, q = self.anchor
        first = fp = at(theta, q, fallback=False)
        if fp.converged:
            return fp
        s, ds = 0.0, 0.5
        while s < 1.0 and ds >= 1.0 / 16:
            step = at(th0 + min(1.0, s + ds) * (theta - th0), q, fallback=False)
            if step.converged:
                s, q = min(1.0, s + ds), step.q
                if s >= 1.0:
                    return step
            else:
                ds *= 0.5
        # the anchor's branch ends (a fold of the fixed-point set): let the damped iteration
        # run from the anchor's Q to wherever it settles (what the warm-started Eq. 15 sweeps
        # would do); L jumps there
        self.branch_jumps += 1
        # (Newton from the anchor's Q at theta is ``first``: not run twice)
        fp = at(theta, self.anchor[1], backups=min(c.max_inner, JUMP_BACKUPS), newton=first)
        if fp.converged:
            return fp
        return FixedPoint(fp.q, False, fp.iterations, fp.residual,
                          f"no fixed point continues the anchor's branch to this theta, and the "
                          f"damped backup from the anchor does not settle ({fp.message})")

    def from_zero_point(self, theta: np.ndarray) -> FixedPoint:
        """The fixed point the damped Eq. 15 iteration reaches from ``Q = 0`` at theta."""
        c = self.config
        fp = iteration_fixed_point(self.features @ theta, self.succ, c.beta, c.gamma,
                                   max_iter=min(NEWTON_CAP, c.max_inner), max_backups=c.max_inner)
        self.newton_iterations += fp.iterations
        return fp

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        """``L``, gradient and the reachable states' ``Q [S', A]`` at theta."""
        c = self.config
        fp = self.solve(theta)
        if not fp.converged:
            return Evaluation(float("nan"), np.full(theta.shape, np.nan), fp.q, ok=False,
                              message=f"Boltzmann fixed point: {fp.message}")
        try:
            dq = boltzmann_dq(fp.q, self.succ, self.features, c.beta, c.gamma)
        except RuntimeError:
            return Evaluation(float("nan"), np.full(theta.shape, np.nan), fp.q, ok=False,
                              message="singular Jacobian at the fixed point (no gradient)")
        ll, g = loglik_grad_from_counts(fp.q, dq, c.beta, self.counts)
        return Evaluation(ll, g, fp.q)

    def full_q(self, theta: np.ndarray, q_reachable: np.ndarray) -> np.ndarray:
        """``[S, A]`` Q on every state, keeping ``q_reachable`` on the reachable ones.

        The reachable block does not depend on the rest, so Newton started from it leaves it
        in place and solves the other states.
        """
        if self.closure.size == self.full_succ.n_states:
            return q_reachable
        c = self.config
        r = self.full_features @ theta
        q0 = r.copy()
        q0[self.closure] = q_reachable
        fp = boltzmann_fixed_point(r, self.full_succ, c.beta, c.gamma, q0=q0, attracting=False,
                                   max_iter=min(NEWTON_CAP, c.max_inner), max_backups=c.max_inner)
        q = fp.q.copy()
        q[self.closure] = q_reachable
        return q


def fit_exact(method: str, demos: Demonstrations, succ: SuccessorModel, config: IRLConfig,
              theta: np.ndarray, progress: bool, start: float, *, from_zero: bool = False) -> FitResult:
    """L-BFGS over theta with exact Boltzmann fixed points (``from_zero``: see
    :class:`ExactBoltzmann`); checks Eq. 15 stability and unbounded weights at the end."""
    ev = ExactBoltzmann(demos, succ, config, from_zero=from_zero)
    counts = demo_counts(demos)
    # searched at each feature's own scale where that is extreme, and "converged" only where the
    # gradient per unit of feature spread is small (on the problem as given); L's size at theta = 0
    # (uniform actions) is the reference of that check
    scale = preconditioner(feature_spread(demos.features, counts))
    asc = lbfgs_ascent(ev.evaluate, theta, config, progress=progress, desc=f"{method} exact",
                       on_accept=ev.accept, scale=scale,
                       reference=float(counts.sum()) * math.log(demos.n_actions))
    message, converged = asc.message, asc.converged
    if from_zero:
        asc, message, converged = _follow_from_zero_branch(ev, asc, config, progress, method)
    extra = {"newton_iterations": float(ev.newton_iterations),
             "branch_jumps": float(ev.branch_jumps),
             "reachable_states": float(ev.closure.size)}
    if ev.branch_loglik is not None:
        extra["loglik_branch"] = float(ev.branch_loglik)
    final = asc.evaluation
    if final.ok:
        stable, lam = iteration_stability(final.q, ev.succ, config.beta, config.gamma)
        extra["stability_eigen"] = float(lam)
        if stable is False:
            converged = False
            message = (f"{message}; the fixed point found repels the damped iteration of Eq. 15 "
                       f"(backup Jacobian eigenvalue with real part {lam:.4g} >= 1): the iterative "
                       f"{method} does not converge to it and the fixed point is not unique")
        unbounded, message = _check_unbounded(ev, theta, asc, message, extra)
        final = replace(final, q=ev.full_q(asc.theta, final.q))
    else:
        converged = False
        full = np.asarray(ev.full_features @ asc.theta)  # Q unknown: report R, flagged not converged
        full[ev.closure] = final.q
        final = replace(final, q=full)
        unbounded = False
    asc = replace(asc, evaluation=final, converged=converged, message=message)
    return result_from_ascent(method, config, asc, time.perf_counter() - start, extra=extra,
                              unbounded=unbounded)


def _follow_from_zero_branch(ev: ExactBoltzmann, asc, config: IRLConfig, progress: bool, method: str):
    """Q-SM's branch rule: the fixed point is the one the Eq. 15 iteration reaches from ``Q = 0``.

    L-BFGS follows a branch of fixed points by continuation; where several fixed points exist the
    branch can end on another one than the iteration from zero reaches at the final theta. The
    result then reports the fixed point from ``Q = 0`` (its ``Q`` and ``L``), the optimised
    branch's ``L`` in ``extra["loglik_branch"]``, and ``converged = False`` (theta was optimised
    on the other branch). Returns ``(ascent, message, converged)``.
    """
    del progress, method
    message, converged = asc.message, asc.converged
    if not asc.evaluation.ok:
        return asc, message, False
    fz = ev.from_zero_point(asc.theta)
    if not fz.converged:
        return asc, (f"{message}; the Eq. 15 iteration from Q = 0 does not settle at the final theta "
                     f"({fz.message}): Q-SM's fixed point is undefined there"), False
    tol = 1e-6 * max(1.0, float(np.max(np.abs(fz.q))))
    if float(np.max(np.abs(fz.q - asc.evaluation.q))) <= tol:
        return asc, f"{message}; Q is the fixed point the Eq. 15 iteration reaches from Q = 0", converged
    branch_ll = asc.evaluation.loglik
    ll = loglik_from_counts(fz.q, config.beta, ev.counts)
    ev.branch_loglik = branch_ll
    asc = replace(asc, evaluation=replace(asc.evaluation, q=fz.q, loglik=ll))
    return asc, (f"{message}; the optimised branch of fixed points (L {branch_ll:.6g}) is not the one the "
                 f"Eq. 15 iteration reaches from Q = 0 at the final theta: reported Q and L ({ll:.6g}) are "
                 f"that iteration's; theta is not its optimum"), False


def _check_unbounded(ev: ExactBoltzmann, theta0: np.ndarray, asc, message: str,
                     extra: dict) -> tuple[bool, str]:
    """Whether the fit ran off along a recession direction (:mod:`irl.unbounded`): candidates are
    the final theta, its displacement from ``theta0`` and the final gradient. With ``l2 > 0`` the
    weights stay finite and the message says so instead."""
    def loglik(th):
        e = ev.evaluate(th)
        return e.loglik if e.ok else None

    theta = np.asarray(asc.theta, dtype=np.float64)
    found = boltzmann_recession(theta, (theta, theta - theta0, asc.evaluation.grad), ev.features, ev.succ,
                                ev.counts, ev.config.gamma, loglik)
    extra["separable"] = float(found is not None)
    if found is None:
        return False, message
    d, further = found
    if ev.config.l2 > 0:
        return False, f"{message}; finite only thanks to l2 = {ev.config.l2} (data are separable)"
    return True, (f"weights unbounded: the demonstrations are separable along direction "
                  f"{np.array2string(d, precision=3)} (the demonstrated actions are optimal under it, "
                  f"so L rises toward its supremum as theta grows along it; L further along: "
                  f"{further:.6g}); loglik {asc.evaluation.loglik:.6g} is where the fit stopped. "
                  f"Set l2 > 0 for finite weights. ({message})")


class DampedBoltzmann(FaithfulSolver):
    """Synchronous damped Boltzmann backup over all pairs (MLIRL faithful), warm-started."""

    def __init__(self, demos: Demonstrations, succ: SuccessorModel, config: IRLConfig):
        super().__init__(demos, config)
        S, A, K = demos.features.shape
        self.shape = (S, A, K)
        self.phi = demos.features.reshape(S * A, K)
        self.succ = succ
        # small models: dense products are far cheaper than sparse ones per sweep
        self.p = succ.p.toarray() if S * A * S <= 2_000_000 else succ.p
        self.q = np.zeros(S * A)
        self.dq = np.zeros((S * A, K))

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        c = self.config
        S, A, K = self.shape
        r = self.phi @ theta
        a, keep = c.alpha, 1.0 - c.alpha
        ok_q = ok_d = False
        for n1 in range(1, c.max_inner + 1):  # noqa: B007 - the sweep count is reported after the loop
            v, _, _ = mean_weights(self.q.reshape(S, A), c.beta)
            new = keep * self.q + a * (r + c.gamma * (self.p @ v))
            change = float(np.max(np.abs(new - self.q)))
            self.q = new
            if not np.isfinite(change):
                break
            if change < c.inner_tol:
                ok_q = True
                break
        _, _, w = mean_weights(self.q.reshape(S, A), c.beta)
        if isinstance(self.p, np.ndarray):  # gamma P W, dense
            m = c.gamma * (self.p[:, :, None] * w[None, :, :]).reshape(S * A, S * A)
        else:
            m = backup_operator(self.succ, w, c.gamma)
        for n2 in range(1, c.max_inner + 1):  # noqa: B007 - the sweep count is reported after the loop
            new = keep * self.dq + a * (self.phi + m @ self.dq)
            change = float(np.max(np.abs(new - self.dq)))
            self.dq = new
            if not np.isfinite(change):
                break
            if change < c.inner_tol:
                ok_d = True
                break
        return self.conclude(self.q.reshape(S, A).copy(), self.dq.reshape(S, A, K), n1 + n2, (ok_q, ok_d))

