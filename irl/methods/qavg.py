"""Q-Avg: model-free maximum-likelihood IRL with the averaging backup (paper Eq. 12/13).

Model-free successors (see :mod:`irl.transitions`): the observed transitions only; pairs with
no observed successor are terminal (``Q = R``), or follow ``config.unobserved``
(:mod:`irl.unobserved_successors`; the exact solver only). The fixed point of the damped sweep with
averaged successors is ``Q = R + gamma P_hat (mean_b Q(s', b))``, linear in theta:
``Q = D theta`` with ``D = (I - gamma M)^-1 Phi`` (:func:`irl.bellman.operators.average_basis`).

* ``exact`` solver: ``L(theta) = sum counts * log softmax(beta D theta)`` is a concave
  multinomial-logit likelihood; damped Newton with the analytic ``K x K`` Hessian finds its
  global maximum, stepping in coordinates scaled by each feature's spread
  (:func:`feature_scale`) so that features in very different units are fitted as well as
  features in one unit; an optimum is reported only where the original problem's gradient at
  the returned theta is small per unit of feature spread (:data:`OPTIMUM_GTOL`). A linear
  programme (:func:`irl.ascent.recession_direction`) checks first whether the data let the
  weights grow without bound; then the reported ``loglik`` is the supremum approached and
  ``unbounded=True`` (use ``l2 > 0`` for a finite answer).
* ``faithful`` solver: the authors' damped in-place sweeps (:mod:`irl.methods.damped_sweeps`), Q then dQ each
  to ``max change < inner_tol`` or ``max_inner`` sweeps, warm-started across outer steps, and
  fixed-length unit-gradient outer steps (:func:`irl.ascent.unit_step_ascent`). Where a pair has
  several different successors, the in-place sweep's fixed point depends on alpha and the data
  order (it is not the averaged one) and may oscillate: the authors' code, run with 10 % slip
  and on NGSIM, never reaches ``inner_tol`` = 1e-4, and every outer step runs both inner loops
  to their 10000-sweep cap.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from irl.ascent import Evaluation, newton_concave, penalised, recession_direction
from irl.bellman.operators import average_basis
from irl.boltzmann import log_policy, loglik_grad_from_counts, step_counts
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.methods.common import fit_faithful, result_from_ascent, start_model_free
from irl.methods.damped_sweeps import compose_sweep, iterate_affine
from irl.methods.faithful import PlannedSweeps
from irl.result import FitResult
from irl.transitions import SuccessorModel, model_free_successors
from irl.unobserved_successors import free_successors


def qavg_basis(demos: Demonstrations, gamma: float, succ: SuccessorModel | None = None) -> np.ndarray:
    """``D [S, A, K]`` with ``Q_avg(theta) = D @ theta`` (exact model-free fixed point).

    ``succ``: the successor model (default: :func:`irl.transitions.model_free_successors`,
    terminal where no successor was observed).
    """
    return average_basis(succ or model_free_successors(demos), demos.features, gamma)


def qavg_q(theta: np.ndarray, demos: Demonstrations, config: IRLConfig,
           fallback_next: np.ndarray | None = None) -> np.ndarray:
    """``[S, A]`` exact Q-Avg fixed point at ``theta [K]`` (for held-out likelihoods / policies),
    with ``config.unobserved`` (and ``fallback_next [S, A]`` for ``"kinematic"``)."""
    succ = free_successors(demos, config, fallback_next)
    return qavg_basis(demos, config.gamma, succ) @ np.asarray(theta, dtype=np.float64)


def logit_hessian(q: np.ndarray, basis: np.ndarray, beta: float, counts: np.ndarray) -> np.ndarray:
    """``d2L/dtheta2 [K, K]`` when ``Q = basis @ theta`` (``basis [S, A, K]``, ``counts [S, A]``).

    ``-beta^2 sum_s n_s Cov_{pi(.|s)}(basis[s])`` with ``n_s`` the steps at s: negative semidefinite.
    """
    n_s = counts.sum(axis=1)
    vis = n_s > 0
    pi = np.exp(log_policy(q[vis], beta))  # [V, A]
    b = basis[vis]  # [V, A, K]
    mean = np.einsum("sa,sak->sk", pi, b)
    centred = b - mean[:, None, :]
    cov = np.einsum("sa,sak,sal->skl", pi, centred, centred)
    return -(beta ** 2) * np.einsum("s,skl->kl", n_s[vis], cov)


def observed_differences(basis: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``[m, K]`` rows ``basis[s, a] - basis[s, b]`` for every observed (s, a) and every b != a."""
    ss, aa = np.nonzero(counts > 0)
    A = basis.shape[1]
    rows = basis[ss, aa][:, None, :] - basis[ss]  # [n_obs, A, K]
    keep = np.ones((ss.size, A), dtype=bool)
    keep[np.arange(ss.size), aa] = False
    return rows[keep]


def feature_scale(basis: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``[K]`` the spread of each feature of ``basis [S, A, K]`` across the actions of the
    visited states (``counts [S, A]`` steps): ``sqrt(sum_s n_s Var_a basis[s, :, k] / sum_s n_s)``,
    the square root of the diagonal of ``-H / beta^2 N`` at ``theta = 0`` (all actions equally
    likely). 1 where a feature does not vary (or nothing is visited).

    Q-Avg's Newton steps in ``u = scale * theta`` (Jacobi preconditioning): a feature in feet
    beside one in miles gives the same fit as both in one unit, up to rounding.
    """
    n_s = counts.sum(axis=1)
    vis = n_s > 0
    if not vis.any():
        return np.ones(basis.shape[2])
    b = basis[vis]
    var = ((b - b.mean(axis=1, keepdims=True)) ** 2).mean(axis=1)  # [V, K]
    s = np.sqrt(n_s[vis] @ var / n_s[vis].sum())
    return np.where(np.isfinite(s) & (s > 0), s, 1.0)


#: Q-Avg's exact solver reports an optimum only where the penalised gradient of the original
#: problem at the returned theta, times each feature's spread (:func:`feature_scale`: the
#: gradient in the scaled coordinates), is at most this times ``max(1, |f|)``. Per unit of
#: spread, because the raw ``|dL/dtheta_k|`` of a feature in tiny units is tiny however far
#: its weight is from the optimum (and that of one in huge units carries its rounding).
OPTIMUM_GTOL = 1e-6
#: Newton's stopping gain (relative) and iteration cap when the LP has shown the weights
#: unbounded: the reported ``loglik`` is the supremum approached, to about this precision.
UNBOUNDED_FTOL = 1e-9
UNBOUNDED_MAX_ITER = 60


def _fit_exact(demos: Demonstrations, config: IRLConfig, theta: np.ndarray, progress: bool,
               succ: SuccessorModel):
    basis = qavg_basis(demos, config.gamma, succ)
    states, actions, _ = demos.flat()
    counts = step_counts(states, actions, demos.n_states, demos.n_actions)
    beta = config.beta

    def evaluate(th: np.ndarray) -> Evaluation:
        q = basis @ th
        ll, g = loglik_grad_from_counts(q, basis, beta, counts)
        return Evaluation(ll, g, q, hess=logit_hessian(q, basis, beta, counts))

    direction = recession_direction(observed_differences(basis, counts))
    separable = direction is not None
    unbounded = separable and config.l2 == 0.0
    scale = feature_scale(basis, counts)
    # unbounded weights are certain from the LP before any step: no need to follow them for long
    asc = newton_concave(evaluate, theta, config, progress=progress, desc="qavg exact",
                         ftol=UNBOUNDED_FTOL if unbounded else 0.0, scale=scale,
                         max_iter=UNBOUNDED_MAX_ITER if unbounded else 500)
    f, g = penalised(asc.evaluation, asc.theta, config.l2)
    g_orig, g_scaled = float(np.max(np.abs(g), initial=0.0)), float(np.max(np.abs(g / scale), initial=0.0))
    extra = {"separable": float(separable), "grad_inf": g_orig, "grad_inf_scaled": g_scaled,
             "feature_scale_ratio": float(scale.max() / scale.min())}
    # relative to L's size, but never to an absurd L's: |L(0)| (uniform actions) bounds |L| at the optimum
    l_zero = float(counts.sum()) * math.log(demos.n_actions)
    tol = OPTIMUM_GTOL * max(1.0, min(abs(f), l_zero))
    if asc.converged and not unbounded and "weights diverge" in asc.message:
        asc = replace(asc, converged=False, message=(
            f"{asc.message}, but the data are not separable (the LP finds no direction of unbounded "
            "likelihood): the weights ran away from a bad start or a rounding-dominated problem, not an optimum"))
    elif asc.converged and not unbounded and g_scaled > tol:
        # the stopping rule held but this is no optimum: say so rather than "optimum reached"
        asc = replace(asc, converged=False, message=(
            f"{asc.message}, but the gradient there is {g_scaled:.3g} per unit of feature spread "
            f"(|g|_inf = {g_orig:.3g} on the original scale) > {tol:.3g}: not an optimum"))
    message = asc.message
    diverged = bool(asc.extra.get("diverged")) and not unbounded
    extra["diverged"] = float(diverged)
    if diverged:
        # stopped early (irl.ascent.stalled): the run-away weights are the finding, not a cap
        message = (f"weights unbounded in practice: {asc.message}. The LP finds no exact separating direction "
                   "(the data are separable up to rounding, or a feature barely varies between actions); "
                   "the weights are not an optimum. Set l2 > 0 for finite weights.")
    elif unbounded and direction is not None:
        d = direction / np.linalg.norm(direction)
        message = (f"weights unbounded: the demonstrations are separable along direction "
                   f"{np.array2string(d, precision=3)} (L never decreases along it), so L has no "
                   f"finite maximiser; loglik {asc.evaluation.loglik:.6g} is the supremum approached. "
                   f"Set l2 > 0 for finite weights. ({asc.message})")
    elif separable:
        message = f"{asc.message}; finite only thanks to l2 = {config.l2} (data are separable)"
    return asc, unbounded or diverged, message, extra


class FaithfulQAvg(PlannedSweeps):
    """The reference code's inner loops for Q-Avg, with warm-started state across outer steps."""

    def __init__(self, demos: Demonstrations, config: IRLConfig):
        super().__init__(demos, config)
        w = np.full(self.shape, 1.0 / self.shape[1])  # Q-Avg: the uniform mean, fixed
        self.gh = compose_sweep(self.plan, w, config.alpha, config.gamma)

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        c = self.config
        r = (self.phi_in @ theta), (self.phi_out @ theta)
        self.x, self.x_out, n1, ok1 = iterate_affine(self.gh, self.x, r[0], self.x_out, r[1],
                                                     c.alpha, c.max_inner, c.inner_tol)
        self.dx, self.dx_out, n2, ok2 = iterate_affine(self.gh, self.dx, self.phi_in, self.dx_out,
                                                       self.phi_out, c.alpha, c.max_inner, c.inner_tol)
        return self.conclude(self.assemble(self.x, self.x_out), self.assemble(self.dx, self.dx_out),
                             n1 + n2, (ok1, ok2))


def fit_qavg(demos: Demonstrations, config: IRLConfig, rng: np.random.Generator, *,
             theta0: np.ndarray | None = None, progress: bool = False,
             fallback_next: np.ndarray | None = None) -> FitResult:
    """Fit Q-Avg weights (``config.solver`` ``"exact"`` or ``"faithful"``); see the module doc.

    ``fallback_next``: ``[S, A]`` int next states of a domain model, for
    ``config.unobserved == "kinematic"`` (:mod:`irl.unobserved_successors`).

    Raises:
        ConfigError: ``fallback_next`` missing or given against ``config.unobserved``.
    """
    start, theta, succ = start_model_free(demos, config, rng, theta0, fallback_next)
    if config.solver == "exact":
        asc, unbounded, message, extra = _fit_exact(demos, config, theta, progress, succ)
        return result_from_ascent("qavg", config, asc, time.perf_counter() - start,
                                  unbounded=unbounded, message=message, extra=extra)
    return fit_faithful("qavg", FaithfulQAvg(demos, config), theta, config, progress, start)
