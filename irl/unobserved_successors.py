"""What Q-Avg and Q-SM bootstrap from at a pair with no observed successor.

The model-free methods take successors from the demonstrations only (:mod:`irl.transitions`).
A pair ``(s, a)`` with no observed successor (an action never taken in ``s``, or taken only at
a trajectory's last step) has nothing to bootstrap from. The paper and the authors' code make
it terminal, ``Q(s, a) = R(s, a)``, while an observed pair collects rewards along its
trajectory's remainder, ``Q ~ R / (1 - gamma)`` for long ones: at gamma 0.99 the two are on
scales some 100x apart inside one state's softmax, and the actions not taken look worse (or
better) only because they were not taken. :data:`irl.config.UNOBSERVED_RULES` names the
choices, set by ``IRLConfig.unobserved``:

* ``"terminal"``: ``Q(s, a) = R(s, a)`` (the paper's; the default of :class:`IRLConfig`).
* ``"self"``: the pair's successor is its own state,
  ``Q(s, a) = R(s, a) + gamma sum_b w(b|s) Q(s, b)`` (``w`` uniform for Q-Avg, Boltzmann for
  Q-SM): the state's value continues, as if the driver stayed where the choice was made. In a
  state no demonstration visited, every pair follows this rule and the policy there is
  ``softmax(beta R(s, .))`` as with ``"terminal"`` (the added ``gamma V(s)`` is the same for every action).
* ``"kinematic"``: the successor a domain model predicts, ``fallback_next[s, a]`` (an ``[S, A]``
  int table given to the fit); for the merge domain
  :func:`irl.domains.merge.mdp.kinematic_successors`, constant-acceleration kinematics over one
  decision step (the paper's fallback for MLIRL's estimated model).

Every rule keeps Q-Avg's fixed point linear in theta (``Q = D theta``,
``D = (I - gamma M)^-1 Phi`` with ``M`` the successor model averaged over actions), so its
likelihood stays concave and its recession check valid. Which rule fits held-out data best is
measured by ``studies/driver_loo.py``.
"""

from __future__ import annotations

import numpy as np

from irl.config import UNOBSERVED_RULES, IRLConfig
from irl.demonstrations import Demonstrations
from irl.errors import ConfigError
from irl.transitions import SuccessorModel, model_free_successors


def fallback_successors(rule: str, n_states: int, n_actions: int,
                        fallback_next: np.ndarray | None = None) -> np.ndarray | None:
    """``[S, A]`` int successor of each pair under ``rule`` (None for ``"terminal"``).

    Args:
        rule: one of :data:`irl.config.UNOBSERVED_RULES`.
        n_states, n_actions: ``S``, ``A``.
        fallback_next: ``[S, A]`` int, the domain model's next states (``"kinematic"`` only).

    Raises:
        ConfigError: unknown rule, ``"kinematic"`` without ``fallback_next``, or
            ``fallback_next`` given with another rule.
    """
    if rule not in UNOBSERVED_RULES:
        raise ConfigError(f"unobserved must be one of {UNOBSERVED_RULES}, got {rule!r}")
    if rule != "kinematic" and fallback_next is not None:
        raise ConfigError(f"fallback_next given but unobserved={rule!r}: it is used by 'kinematic' only")
    if rule == "terminal":
        return None
    if rule == "self":
        return np.repeat(np.arange(n_states, dtype=np.int64)[:, None], n_actions, axis=1)
    if fallback_next is None:
        raise ConfigError("unobserved='kinematic' needs the domain's next-state table fallback_next [S, A] "
                          "(the merge domain supplies it: irl.domains.merge.mdp.kinematic_successors)")
    return np.asarray(fallback_next)


def free_successors(demos: Demonstrations, config: IRLConfig,
                    fallback_next: np.ndarray | None = None) -> SuccessorModel:
    """The model-free successor model of ``demos`` under ``config.unobserved`` (module doc).

    Raises:
        ConfigError: see :func:`fallback_successors`.
        DemonstrationError: ``fallback_next`` is not ``[S, A]`` valid states.
    """
    nxt = fallback_successors(config.unobserved, demos.n_states, demos.n_actions, fallback_next)
    return model_free_successors(demos, nxt)
