"""The closed-loop targets for one learned driver, judged on an evaluation's aggregates.

Four checks (:func:`target_checks`), each a line of text and whether it is met:

* 0 collisions by the controlled cars A (the text gives the count and the Wilson 95 % upper bound);
* held-out log-likelihood per step (nats) above both ``marginal`` and ``bc``;
* the Wasserstein distance of A's speed (ft/s) and of the gap d_AC to the lead car C (ft) to
  the held-out demonstrations at most 1.5 times the floor's, where the floor
  (:func:`floor_driver`) is the demonstrators' own driver in the closed loop: its distance to
  held-out runs on other seeds is sampling noise alone.

``studies/closed_loop_target.py`` prints them after its evaluation; nothing here runs SUMO.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from analysis.evaluation.aggregate import AggregateMetrics

#: How many times the floor's Wasserstein distance a driver may be from the demonstrations.
W1_FACTOR = 1.5


def _f(x: float, nd: int = 3) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def floor_driver(encounter_rule: str) -> str:
    """The SUMO-driver floor of the Wasserstein targets: the demonstrators' own driver in the
    closed loop, whose distance to the held-out demonstrations on other seeds is sampling noise
    alone. With ``in-lane`` demonstrations (A's lane held while observed) that is
    ``sumo-in-lane``; with the ``take-over`` and ``merge-frame`` rules (lanes free) ``sumo``."""
    return "sumo-in-lane" if encounter_rule == "in-lane" else "sumo"


def target_checks(name: str, aggs: Mapping[str, AggregateMetrics], floor: str = "sumo") -> list[tuple[str, bool]]:
    """The closed-loop targets for the driver ``name``: ``[(text, met)]``, four pairs in
    the order of the module docstring, the Wasserstein ones against the driver ``floor``
    (:func:`floor_driver`). A NaN figure fails its check.

    Args:
        name: the driver judged, a key of ``aggs``.
        aggs: every policy's aggregates of one evaluation (:class:`AggregateMetrics`, or any
            object with its ``a_collisions``, ``n_controls``, ``a_collision_ci95``,
            ``heldout_loglik_per_step``, ``w1_speed_A_ft_s`` and ``w1_d_AC_ft``); must hold
            ``name``, ``floor``, ``marginal`` and ``bc``.
        floor: the driver whose distances set the Wasserstein targets.

    Raises:
        KeyError: one of those four policies is not in ``aggs``.
    """
    d, ref = aggs[name], aggs[floor]
    marginal, bc = aggs["marginal"].heldout_loglik_per_step, aggs["bc"].heldout_loglik_per_step
    k = W1_FACTOR
    return [
        (f"{name}: 0 collisions by controlled cars ({d.a_collisions}/{d.n_controls}, 95 % upper bound "
         f"{_f(d.a_collision_ci95[1])})", d.a_collisions == 0),
        (f"{name}: held-out LL/step {_f(d.heldout_loglik_per_step)} > marginal {_f(marginal)} and bc {_f(bc)}",
         d.heldout_loglik_per_step > max(marginal, bc)),
        (f"{name}: W1 speed {_f(d.w1_speed_A_ft_s, 2)} <= {k} x {floor} {_f(ref.w1_speed_A_ft_s, 2)}",
         d.w1_speed_A_ft_s <= k * ref.w1_speed_A_ft_s),
        (f"{name}: W1 d_AC {_f(d.w1_d_AC_ft, 1)} <= {k} x {floor} {_f(ref.w1_d_AC_ft, 1)}",
         d.w1_d_AC_ft <= k * ref.w1_d_AC_ft),
    ]
