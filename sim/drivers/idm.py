"""The Intelligent Driver Model as a reference driver through the controller (``idm``).

:class:`IdmPolicy` drives car A by the IDM acceleration (Treiber, Hennecke & Helbing 2000,
Phys. Rev. E 62, 1805) ``a_max (1 - (v/v0)^4 - (s*/s)^2)`` towards A's leader (the lead car C;
once B has merged into lane 6 ahead of A and nearer than C, B; free road without either), with ``s* = s0 + v T + v dv / (2 sqrt(a_max b))``, and takes the action whose bin
holds that acceleration (:func:`irl.domains.merge.actions.action_of`, the rule that labels the
demonstrations), deterministically. The controller applies it as every policy's action: at
``action_acc_ft_s2``, once per decision step, with SUMO's own safety checks off.

It answers a question the other rows cannot: how far from the demonstrations does a driver get
that follows its lead car by the formula and parameters of the synthetic demonstrators'
car-following model (:meth:`IdmPolicy.from_scenario` takes the scenario's car type; SUMO
integrates the same formula in sub-steps) but acts only through the five
actions at the decision step and does not yield to the merging car B (which SUMO's lane-change
model makes the demonstrators do)? docs/closed-loop.md has the measurement.

Limits: it does not yield to B before B merges, and :meth:`IdmPolicy.from_scenario` takes the
first car type's parameters as IDM's whatever that type's car-following model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from irl.domains.merge.actions import ACTION_ACC_FT_S2, N_ACTIONS, action_of
from irl.domains.merge.car_following import GapNeed
from merge_irl.units import FT_PER_M
from sim.drivers.observe import MergeObservation
from sim.drivers.policy import NO_LIKELIHOOD, PolicyDefaults

#: The bound of ``(s*/s)^2``: braking is at most ``a_max x 1000``, far beyond any action's bin.
IDM_NEED_CLIP = 1000.0


@dataclass(frozen=True)
class IdmPolicy(PolicyDefaults):
    """IDM towards A's leader as a driver (module docstring).

    Attributes:
        gap_need: the IDM parameters (ft, s, ft/s^2, ft/s): ``min_gap_ft`` (s0),
            ``time_headway_s`` (T), ``accel_ft_s2`` (a_max), ``decel_ft_s2`` (b),
            ``desired_speed_ft_s`` (v0), ``length_ft`` (the leader's length where the
            observation has none; otherwise ``len_C`` or ``len_B`` is subtracted from the gap).
        name: label in reports (``idm``).
        action_acc_ft_s2: ``[5]`` acceleration applied per action (ft/s^2).
        delta: the free-road exponent (4, SUMO's and Treiber's default).
    """

    gap_need: GapNeed = field(default_factory=lambda: GapNeed(clip=IDM_NEED_CLIP))
    name: str = "idm"
    controls: bool = True
    action_acc_ft_s2: tuple[float, ...] = tuple(float(x) for x in ACTION_ACC_FT_S2)
    delta: float = 4.0

    @classmethod
    def from_scenario(cls, spec, **kw) -> IdmPolicy:
        """IDM with the parameters of ``spec``'s first car type (``drivers.car[0]``: minGap, tau,
        accel, decel, length) and its desired speed ``min(maxSpeed, speed limit x speedFactor)``,
        as SUMO sets it for that type (without the per-vehicle speed deviation). ``kw``: further
        fields (``name``, ``action_acc_ft_s2``)."""
        car = spec.drivers.car[0]
        v0 = min(car.max_speed_mps, spec.road.speed_limit_mps * car.speed_factor)
        need = GapNeed(min_gap_ft=car.min_gap_m * FT_PER_M, time_headway_s=car.tau, accel_ft_s2=car.accel * FT_PER_M,
                       decel_ft_s2=car.decel * FT_PER_M, desired_speed_ft_s=v0 * FT_PER_M,
                       length_ft=car.length_m * FT_PER_M, clip=IDM_NEED_CLIP)
        return cls(gap_need=need, **kw)

    def idm_acceleration(self, obs: MergeObservation) -> float:
        """The IDM acceleration (ft/s^2) at ``obs``: towards B (``d_AB``, ``v_AB``) when
        ``b_merged`` and B is ahead of A and nearer than C, else towards C (``d_AC``, ``v_AC``);
        free road when neither applies (``d_AC`` NaN). The bumper gap is the front-to-front
        gap minus the leader's length (``len_B`` or ``len_C``; ``length_ft`` if unknown)."""
        g = self.gap_need
        v = max(obs.speed_A, 0.0)
        free = 1.0 - (v / g.desired_speed_ft_s) ** self.delta
        gap, dv, length = obs.d_AC, obs.v_AC, obs.len_C
        if obs.b_merged and obs.d_AB > 0 and not (np.isfinite(gap) and gap <= obs.d_AB):
            gap, dv, length = obs.d_AB, obs.v_AB, obs.len_B
        if not np.isfinite(gap):
            return g.accel_ft_s2 * free
        return g.accel_ft_s2 * (free - float(g.need(gap, v, dv, length)))

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]``: probability 1 on the action whose bin holds :meth:`idm_acceleration`."""
        p = np.zeros(N_ACTIONS)
        p[action_of(self.idm_acceleration(obs))] = 1.0
        return p

    @property
    def decision_step_s(self) -> None:
        """Any step (IDM is not trained)."""
        return None

    def heldout_loglik(self, encounters: pd.DataFrame, *, decision_step_s: float,
                       where: str) -> tuple[float, float]:
        """NaN, NaN: a deterministic reference driver has no likelihood to speak of."""
        return NO_LIKELIHOOD
