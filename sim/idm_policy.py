"""The Intelligent Driver Model as a reference driver through the controller (``idm``).

:class:`IdmPolicy` drives car A by the IDM acceleration (Treiber, Hennecke & Helbing 2000,
Phys. Rev. E 62, 1805) ``a_max (1 - (v/v0)^4 - (s*/s)^2)`` towards the lead car C (free road
without C), with ``s* = s0 + v T + v dv / (2 sqrt(a_max b))``, and takes the action whose bin
holds that acceleration (:func:`irl.domains.merge_actions.action_of`, the rule that labels the
demonstrations), deterministically. The controller applies it as every policy's action: at
``action_acc_ft_s2``, once per decision step, with SUMO's own safety checks off.

It answers a question the other rows cannot: how far from the demonstrations does a driver get
that follows its lead car by the formula and parameters of the synthetic demonstrators'
car-following model (:meth:`IdmPolicy.from_scenario` takes the scenario's car type; SUMO
integrates the same formula in sub-steps) but acts only through the five
actions at the decision step and does not yield to the merging car B (which SUMO's lane-change
model makes the demonstrators do)? docs/closed-loop.md has the measurement.

Limits: it follows C alone, also after B has merged ahead of A during the controller's hold (the
observation does not say whether B is in lane 6), and :meth:`IdmPolicy.from_scenario` takes the
first car type's parameters as IDM's whatever that type's car-following model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from irl.domains.merge_actions import ACTION_ACC_FT_S2, N_ACTIONS, action_of
from irl.domains.merge_car_following import GapNeed
from irl.units import FT_PER_M
from sim.observe import MergeObservation

#: The bound of ``(s*/s)^2``: braking is at most ``a_max x 1000``, far beyond any action's bin.
IDM_NEED_CLIP = 1000.0


@dataclass(frozen=True)
class IdmPolicy:
    """IDM towards C as a driver (module docstring).

    Attributes:
        gap_need: the IDM parameters (ft, s, ft/s^2, ft/s): ``min_gap_ft`` (s0),
            ``time_headway_s`` (T), ``accel_ft_s2`` (a_max), ``decel_ft_s2`` (b),
            ``desired_speed_ft_s`` (v0), ``length_ft`` (C's length, subtracted from ``d_AC``).
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

    def acceleration(self, obs: MergeObservation) -> float:
        """The IDM acceleration (ft/s^2) at ``obs`` (``speed_A``, ``d_AC``, ``v_AC``; free road
        when ``d_AC`` is NaN)."""
        g = self.gap_need
        free = 1.0 - (max(obs.speed_A, 0.0) / g.desired_speed_ft_s) ** self.delta
        if not np.isfinite(obs.d_AC):
            return g.accel_ft_s2 * free
        need = float(g.need(obs.d_AC, max(obs.speed_A, 0.0), obs.v_AC))
        return g.accel_ft_s2 * (free - need)

    def probs(self, obs: MergeObservation) -> np.ndarray:
        """``[5]``: probability 1 on the action whose bin holds :meth:`acceleration`."""
        p = np.zeros(N_ACTIONS)
        p[action_of(self.acceleration(obs))] = 1.0
        return p
