"""State the faithful (reference-code) solvers share: warm-started inner loops and their tally.

Each faithful solver keeps its inner iterates from one outer step to the next (the reference
code's warm start) and counts, for :func:`irl.methods.common.finish_faithful`, how many inner
sweeps ran, how many inner loops hit ``max_inner`` and whether the last step's loops converged.
"""

from __future__ import annotations

import numpy as np

from irl.ascent import Evaluation
from irl.boltzmann import demo_counts, loglik_grad_from_counts
from irl.config import IRLConfig
from irl.demonstrations import Demonstrations
from irl.methods.damped_sweeps import make_plan


class FaithfulSolver:
    """Demonstration counts ``[S, A]`` and the inner-loop tally (``sweeps``, ``inner_caps``, ``last_ok``)."""

    def __init__(self, demos: Demonstrations, config: IRLConfig):
        self.config = config
        self.counts = demo_counts(demos)
        self.sweeps = 0
        self.inner_caps = 0
        self.last_ok = True

    def conclude(self, q: np.ndarray, dq: np.ndarray, sweeps: int, converged: tuple[bool, ...]) -> Evaluation:
        """Tally one outer step's inner loops, then ``L`` and ``dL/dtheta`` at ``q [S, A]``, ``dq [S, A, K]``."""
        self.sweeps += sweeps
        self.inner_caps += sum(not ok for ok in converged)
        self.last_ok = all(converged)
        ll, g = loglik_grad_from_counts(q, dq, self.config.beta, self.counts)
        finite = bool(np.isfinite(ll) and np.all(np.isfinite(g)))
        return Evaluation(ll, g, q, ok=finite, message="" if finite else "non-finite Q or dQ")


class PlannedSweeps(FaithfulSolver):
    """A model-free faithful solver's iterates, split by its :class:`irl.methods.damped_sweeps.SweepPlan`.

    ``x [n_active]`` / ``x_out [n_outside]``: Q of the swept pairs and of the others;
    ``dx [n_active, K]`` / ``dx_out [n_outside, K]``: their dQ/dtheta; ``phi_in`` /
    ``phi_out``: the features of the same pairs. All start at zero.
    """

    def __init__(self, demos: Demonstrations, config: IRLConfig):
        super().__init__(demos, config)
        self.plan = make_plan(demos)
        S, A, K = demos.features.shape
        self.shape = (S, A)
        phi = demos.features.reshape(S * A, K)
        self.phi_in, self.phi_out = phi[self.plan.active], phi[self.plan.outside]
        self.x = np.zeros(self.plan.n_active)
        self.x_out = np.zeros(self.plan.outside.size)
        self.dx = np.zeros((self.plan.n_active, K))
        self.dx_out = np.zeros((self.plan.outside.size, K))

    def assemble(self, x_in: np.ndarray, x_out: np.ndarray) -> np.ndarray:
        """Swept and other pairs' values back into one ``[S, A, ...]`` array."""
        S, A = self.shape
        full = np.zeros((S * A,) + x_in.shape[1:])
        full[self.plan.active] = x_in
        full[self.plan.outside] = x_out
        return full.reshape((S, A) + x_in.shape[1:])
