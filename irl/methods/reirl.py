"""Relative-entropy IRL (Boularias, Kober and Peters 2011) through its convex dual.

With baseline trajectories ``i = 1..n`` sampled by a uniform-random policy, discounted feature
counts ``f_i = sum_t gamma^t phi(s_t, a_t)`` (``[n, K]``), importance weights ``w_i`` and the
experts' mean counts ``f_E`` (``[K]``), the learned weights solve

    min_theta  log sum_i w_i exp(theta . f_i)  -  theta . f_E  +  eps ||theta||_1 .

Importance weights: the sampling policy is uniform, so the ratio between the trajectory
distribution under the sampling policy and under the reference (uniform) policy is the same for
every trajectory: the transition probabilities cancel and ``w_i = 1/n``.

Padding (paper section 4.1): every trajectory, expert or baseline, is prolonged to the length
of the longest one by repeating its last (state, action) pair; a caller may pass ``pad_step``
instead (for the merge domain, constant-velocity motion: see ``irl.domains.merge.mdp``).

The L1 weight ``eps`` (one per feature) is by default the confidence bound of the experts'
feature-count estimate, as Boularias et al. derive it with Hoeffding's inequality: with ``n``
expert trajectories whose discounted counts of feature ``k`` lie in an interval of width
``w_k = (max phi_k - min phi_k) (1 - gamma^T) / (1 - gamma)`` (``T`` the padded length),
``|f_E,k - E f_k| <= eps_k = w_k sqrt(ln(2 / delta) / (2 n))`` with probability ``1 - delta``
(:func:`hoeffding_epsilon`, ``delta`` 0.05). Two outcomes are reported as what they are, never as
a fit: the dual unbounded below (the primal is **infeasible**: no reweighting of the baseline
matches the experts' counts within eps; theta is capped at ``theta_cap``) and all weights zero
(the experts are indistinguishable from the baseline at this confidence: **uninformative**).
Both set ``converged = False`` and appear in ``FitResult.flags``.

The problem is convex with one optimum: ``theta0`` and ``rng`` do not change the solution
(``rng`` only draws the baseline trajectories when none are given). The final log-likelihood
(Eq. 5 sum) is computed by solving the MDP for the learned theta with ``irl.methods.mlirl.solve_q``
under ``transitions``.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from irl.boltzmann import loglik_from_counts, step_counts
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError, DemonstrationError, IRLError
from irl.methods.mlirl import solve_q
from irl.result import FitResult
from irl.transitions import TransitionModel, checked_model, estimate_transitions, model_successors

#: Default L1 weight ``eps`` of the dual: None means the Hoeffding bound (:func:`hoeffding_epsilon`).
DEFAULT_EPSILON = None
#: Default ``delta`` of the Hoeffding bound (confidence ``1 - delta``).
DEFAULT_DELTA = 0.05
#: Default number of generated baseline trajectories.
DEFAULT_N_BASELINE = 100
#: Box bound on ``|theta_k|`` applied when the dual is unbounded below.
THETA_CAP = 1e4

PadStep = Callable[[int], tuple[int, int]]


class REIRLError(IRLError):
    """The REIRL dual could not be solved."""


def pad_trajectories(
    states: tuple[np.ndarray, ...], actions: tuple[np.ndarray, ...], length: int,
    pad_step: PadStep | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Prolong every trajectory to ``length`` steps.

    Args:
        states, actions: ragged ``[T_i]`` arrays, ``T_i <= length``.
        pad_step: ``last_state -> (next_state, action)`` for each added step; ``None`` repeats the
            last (state, action) pair (the paper's gridworld rule).

    Returns:
        ``states [n, length]``, ``actions [n, length]``.

    Raises:
        DemonstrationError: a trajectory is longer than ``length``.
    """
    n = len(states)
    out_s = np.empty((n, length), dtype=np.int64)
    out_a = np.empty((n, length), dtype=np.int64)
    for i, (s, a) in enumerate(zip(states, actions)):
        t = s.size
        if t > length:
            raise DemonstrationError(f"trajectory {i} has {t} steps, more than the padding length {length}")
        out_s[i, :t] = s
        out_a[i, :t] = a
        if pad_step is None:
            out_s[i, t:] = s[-1]
            out_a[i, t:] = a[-1]
        else:
            cur = int(s[-1])
            for k in range(t, length):
                cur, act = pad_step(cur)
                out_s[i, k], out_a[i, k] = cur, act
    return out_s, out_a


def discounted_counts(states: np.ndarray, actions: np.ndarray, features: np.ndarray, gamma: float) -> np.ndarray:
    """``[n, K]`` ``sum_t gamma^t phi(s_t, a_t)`` of padded ``states, actions [n, T]``."""
    disc = gamma ** np.arange(states.shape[1])
    return np.einsum("t,ntk->nk", disc, features[states, actions])


def hoeffding_epsilon(features: np.ndarray, n_trajectories: int, length: int, gamma: float,
                      delta: float = DEFAULT_DELTA) -> np.ndarray:
    """``[K]`` confidence bound of the experts' mean discounted feature counts (Hoeffding).

    ``eps_k = w_k sqrt(ln(2/delta) / (2 n))`` with ``w_k = (max phi_k - min phi_k) sum_{t<T} gamma^t``
    (Boularias, Kober and Peters 2011, section 3: the counts of one trajectory lie in an
    interval of width ``w_k``). ``features`` is ``[S, A, K]``; ``length`` is ``T``.

    Raises:
        ConfigError: ``delta`` not in (0, 1) or ``n_trajectories < 1``.
    """
    if not 0.0 < delta < 1.0:
        raise ConfigError(f"REIRL delta must be in (0, 1), got {delta}")
    if int(n_trajectories) < 1:
        raise ConfigError(f"n_trajectories must be >= 1, got {n_trajectories}")
    phi = np.asarray(features, dtype=np.float64).reshape(-1, features.shape[-1])
    width = (phi.max(axis=0) - phi.min(axis=0)) * float(np.sum(gamma ** np.arange(int(length))))
    return width * np.sqrt(np.log(2.0 / delta) / (2.0 * int(n_trajectories)))


def dual_objective(theta: np.ndarray, f_base: np.ndarray, f_expert: np.ndarray, log_w: np.ndarray, eps) -> float:
    """The dual's value at ``theta [K]`` (``f_base [n, K]``, ``f_expert [K]``, ``log_w [n]``;
    ``eps`` a number or ``[K]``)."""
    from scipy.special import logsumexp

    return float(logsumexp(f_base @ theta + log_w) - f_expert @ theta + np.sum(eps * np.abs(theta)))


def dual_smooth_grad(theta: np.ndarray, f_base: np.ndarray, f_expert: np.ndarray, log_w: np.ndarray) -> np.ndarray:
    """``[K]`` gradient of the smooth part ``log sum_i w_i exp(theta . f_i) - theta . f_E``."""
    from scipy.special import softmax

    p = softmax(f_base @ theta + log_w)
    return f_base.T @ p - f_expert


def solve_dual(
    f_base: np.ndarray, f_expert: np.ndarray, log_w: np.ndarray, eps, theta_cap: float | None = None
) -> tuple[np.ndarray, str, float]:
    """Minimise the dual with cvxpy (Clarabel, then SCS if Clarabel fails).

    Args:
        f_base: ``[n, K]`` baseline feature counts; f_expert: ``[K]``; log_w: ``[n]`` log weights.
        eps: L1 weight (>= 0), a number or one per feature ``[K]``.
        theta_cap: if given, constrain ``|theta_k| <= theta_cap``.

    Returns:
        ``(theta [K], cvxpy status, optimal value)``; status ``"unbounded"`` when the dual has no
        minimiser (only possible without ``theta_cap``).

    Raises:
        REIRLError: neither Clarabel nor SCS solves the dual.
    """
    import cvxpy as cp

    k = f_base.shape[1]
    theta = cp.Variable(k)
    eps_k = np.broadcast_to(np.asarray(eps, dtype=np.float64), (k,))
    objective = cp.log_sum_exp(f_base @ theta + log_w) - f_expert @ theta + eps_k @ cp.abs(theta)
    constraints = [cp.abs(theta) <= theta_cap] if theta_cap is not None else []
    problem = cp.Problem(cp.Minimize(objective), constraints)
    status = "solver_error"
    for solver in ("CLARABEL", "SCS"):
        try:
            problem.solve(solver=solver)
        except cp.error.SolverError:
            continue
        status = str(problem.status)
        if status in (cp.OPTIMAL, cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE, cp.OPTIMAL_INACCURATE):
            break
    if status in (cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE):
        return np.full(k, np.nan), "unbounded", -np.inf
    if theta.value is None:
        raise REIRLError(f"REIRL dual not solved by Clarabel or SCS (status {status})")
    return np.asarray(theta.value, dtype=np.float64), status, float(problem.value)


def uniform_baseline(
    demos: Demonstrations, transitions: TransitionModel, n: int, length: int, rng: np.random.Generator
) -> Demonstrations:
    """``n`` uniform-random-policy trajectories of ``length`` steps under ``transitions [S, A, S]``
    (any :data:`~irl.transitions.TransitionModel` form), each starting in a uniformly drawn expert
    start state.

    Each step draws ``u`` uniform and moves to the first successor whose cumulative probability
    exceeds ``u`` times the row total (the successors in state order), so a dense and a sparse
    ``T`` give the same trajectories for one seed.
    """
    succ = model_successors(transitions, n_actions=demos.n_actions)
    indptr, indices, data = succ.p.indptr, succ.p.indices, succ.p.data
    cum = np.empty_like(data)  # per row, the cumulative sum of its stored probabilities
    for i in range(succ.n_pairs):
        lo, hi = indptr[i], indptr[i + 1]
        np.cumsum(data[lo:hi], out=cum[lo:hi])
    starts = np.array([s[0] for s in demos.states])
    A = demos.n_actions
    states, actions = [], []
    for _ in range(int(n)):
        s = int(rng.choice(starts))
        ss = np.empty(length, dtype=np.int64)
        aa = rng.integers(A, size=length)
        for t in range(length):
            ss[t] = s
            i = s * A + int(aa[t])
            row = cum[indptr[i]:indptr[i + 1]]
            k = min(int(np.searchsorted(row, rng.random() * row[-1], side="right")), row.size - 1)
            s = int(indices[indptr[i] + k])
        states.append(ss)
        actions.append(aa.astype(np.int64))
    return Demonstrations(tuple(states), tuple(actions), demos.features, demos.n_states, demos.n_actions,
                          source="uniform-random baseline")


def fit_reirl(
    demos: Demonstrations,
    config: IRLConfig,
    rng: np.random.Generator,
    *,
    baseline: Demonstrations | None = None,
    transitions: TransitionModel | None = None,
    theta0: np.ndarray | None = None,
    epsilon: float | None = DEFAULT_EPSILON,
    n_baseline: int = DEFAULT_N_BASELINE,
    delta: float = DEFAULT_DELTA,
    pad_step: PadStep | None = None,
    theta_cap: float = THETA_CAP,
    progress: bool = False,
) -> FitResult:
    """Fit REIRL weights and evaluate them by the Eq. 5 log-likelihood of the solved MDP.

    Args:
        demos: expert demonstrations (features ``[S, A, K]``).
        config: ``gamma`` discounts the feature counts and the MDP; ``beta`` the final policy.
        rng: draws the baseline trajectories when ``baseline`` is None.
        baseline: non-expert trajectories over the same MDP; default: ``n_baseline`` uniform-
            random trajectories under ``transitions``, as long as the longest expert trajectory.
        transitions: ``[S, A, S]`` model (dense, sparse ``[S*A, S]`` or a
            :class:`~irl.transitions.SuccessorModel`), for generating the baseline and for the
            final log-likelihood; default: estimated from ``demos`` (``irl.transitions``).
        theta0: ignored (the dual is convex with one optimum); accepted for the shared interface.
        epsilon: L1 weight ``eps`` of the dual; None: per feature, the Hoeffding bound of the
            experts' feature-count estimate at confidence ``1 - delta`` (:func:`hoeffding_epsilon`).
        pad_step: how trajectories are prolonged (see ``pad_trajectories``).
        theta_cap: bound on ``|theta_k|`` used only when the dual is unbounded below.
        progress: unused (a single convex solve).

    Returns:
        FitResult with ``loglik_trace``/``theta_trace`` of length 1; ``unbounded`` and
        ``extra["infeasible"] = 1`` when the dual has no minimiser (theta is then the minimiser
        within ``|theta_k| <= theta_cap``); ``extra["uninformative"] = 1`` when every weight is 0.
        Either sets ``converged = False`` (see ``FitResult.flags``).

    Raises:
        ConfigError: negative ``epsilon``, bad ``delta``, ``theta_cap`` or transitions shape.
    """
    del theta0, progress
    start = time.perf_counter()
    if epsilon is not None and not epsilon >= 0:
        raise ConfigError(f"REIRL epsilon must be >= 0, got {epsilon}")
    if not theta_cap > 0:
        raise ConfigError(f"REIRL theta_cap must be positive, got {theta_cap}")
    model = estimate_transitions(demos) if transitions is None else checked_model(transitions, demos)
    longest = max(s.size for s in demos.states)
    baseline = _baseline_of(demos, model, baseline, n_baseline, longest, rng)
    length = max(longest, max(s.size for s in baseline.states))
    phi = np.asarray(demos.features)
    f_expert, f_base = _feature_counts(demos, baseline, length, pad_step, config.gamma)
    log_w = np.full(f_base.shape[0], -np.log(f_base.shape[0]))
    eps = (hoeffding_epsilon(phi, demos.n_trajectories, length, config.gamma, delta) if epsilon is None
           else np.full(phi.shape[2], float(epsilon)))
    theta, status, value = solve_dual(f_base, f_expert, log_w, eps)
    unbounded = status == "unbounded"
    if unbounded:
        theta, status, value = solve_dual(f_base, f_expert, log_w, eps, theta_cap=theta_cap)
    message = f"cvxpy status {status}; dual value {value:.6g}"
    converged = status == "optimal"
    q, q_failure = _final_q(theta, phi, model, config)
    if q_failure:
        converged = False
        message += q_failure
    ll = loglik_from_counts(q, config.beta, step_counts(*demos.flat()[:2], demos.n_states, demos.n_actions))
    uninformative = not unbounded and bool(np.all(np.abs(theta) <= 1e-6 * max(1.0, float(np.max(np.abs(f_base))))))
    if unbounded or uninformative:
        converged = False
        message += _verdict(unbounded, eps, theta_cap)
    if uninformative:
        theta = np.zeros_like(theta)
    return FitResult(
        method="reirl",
        theta=theta,
        loglik=ll,
        q=q,
        config=config,
        loglik_trace=np.array([ll]),
        theta_trace=theta[None, :].copy(),
        converged=converged,
        message=message,
        wall_time_s=time.perf_counter() - start,
        unbounded=unbounded,
        extra={"dual_value": value, "epsilon": float(np.mean(eps)), "n_baseline": float(f_base.shape[0]),
               "pad_length": float(length), "init_independent": 1.0, "infeasible": float(unbounded),
               "uninformative": float(uninformative), "epsilon_hoeffding": float(epsilon is None),
               **{f"epsilon_{k}": float(e) for k, e in enumerate(eps)}},
    )


def _baseline_of(demos: Demonstrations, model, baseline: Demonstrations | None, n_baseline: int,
                 longest: int, rng: np.random.Generator) -> Demonstrations:
    """The baseline trajectories: ``baseline`` checked against the experts' MDP, or ``n_baseline``
    uniform-random trajectories of ``longest`` steps under ``model`` when it is None.

    Raises:
        ConfigError: ``n_baseline < 1`` (when drawn).
        DemonstrationError: ``baseline`` has another number of states or actions.
    """
    if baseline is None:
        if int(n_baseline) < 1:
            raise ConfigError(f"n_baseline must be >= 1, got {n_baseline}")
        return uniform_baseline(demos, model, int(n_baseline), longest, rng)
    if (baseline.n_states, baseline.n_actions) != (demos.n_states, demos.n_actions):
        raise DemonstrationError(
            f"baseline {baseline.source}: {baseline.n_states} states x {baseline.n_actions} actions, "
            f"experts have {demos.n_states} x {demos.n_actions}"
        )
    return baseline


def _feature_counts(demos: Demonstrations, baseline: Demonstrations, length: int,
                    pad_step: PadStep | None, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """``(f_expert [K], f_base [m, K])``: the experts' mean and the baseline's per-trajectory
    discounted feature counts, every trajectory padded to ``length`` steps."""
    phi = np.asarray(demos.features)
    es, ea = pad_trajectories(demos.states, demos.actions, length, pad_step)
    bs, ba = pad_trajectories(baseline.states, baseline.actions, length, pad_step)
    return discounted_counts(es, ea, phi, gamma).mean(axis=0), discounted_counts(bs, ba, phi, gamma)


def _final_q(theta: np.ndarray, phi: np.ndarray, model, config: IRLConfig) -> tuple[np.ndarray, str]:
    """``(q [S, A], failure)``: the Boltzmann Q of the MDP for ``theta`` and ``""``; where it has
    no computable fixed point, ``Q = R = phi @ theta`` and the message suffix saying so."""
    try:
        return np.asarray(solve_q(theta, phi, model, config)), ""
    except IRLError as e:  # the MDP for this theta has no computable Boltzmann fixed point
        return phi @ theta, f"; solving the MDP for the learned theta failed ({e}): loglik uses Q = R"


def _verdict(unbounded: bool, eps: np.ndarray, theta_cap: float) -> str:
    """The message suffix of a dual without minimiser (``unbounded``) or with every weight 0."""
    eps_text = np.array2string(eps, precision=3)
    if unbounded:
        return (f"; INFEASIBLE: the dual is unbounded below (no reweighting of the baseline matches the "
                f"experts' feature counts within eps = {eps_text}); theta is only the minimiser within "
                f"|theta_k| <= {theta_cap:g} and must not be used as a driver")
    return (f"; UNINFORMATIVE: every weight is 0 (the experts' feature counts lie within eps = "
            f"{eps_text} of the baseline's: indistinguishable at this confidence)")


def problem_options(problem, config: IRLConfig, *, epsilon: float | None = DEFAULT_EPSILON,
                    n_baseline: int = DEFAULT_N_BASELINE, **_: object) -> dict:
    """REIRL's options from an :class:`irl.problems.Problem` (the method registry's
    ``problem_options``): its baseline trajectories (None: generated), the L1 weight
    ``epsilon``, ``n_baseline`` and the domain's padding rule."""
    return dict(baseline=problem.baseline, epsilon=epsilon, n_baseline=n_baseline, pad_step=problem.pad_step())
