"""Settings of the closed-loop controller (:class:`sim.closed_loop.controller.Controller`) and the error
raised for bad ones."""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.errors import SimError


class ControllerError(SimError, ValueError):
    """Bad controller settings."""


#: How the High Brake action is applied (:attr:`ControllerConfig.high_brake`).
HIGH_BRAKE_RULES = ("mean", "need")
#: How a driver with a fitted decision rule decides (:attr:`ControllerConfig.rule`).
DECISION_RULES = ("fitted", "likelihood-draw")


@dataclass(frozen=True)
class ControllerConfig:
    """Settings of :class:`~sim.closed_loop.controller.Controller`.

    Attributes:
        decision_step_s: time between two decisions (s); rounded to whole frames. None: the
            policy's own ``decision_step_s`` (a learned model decides on the step its
            demonstrations were resampled to), else 0.3 s.
        mode: take the most likely action of the driver's probabilities instead of sampling them
            (a driver without a fitted decision rule, or ``rule="likelihood-draw"``).
        rule: how a driver with a fitted decision rule (``decide``,
            :func:`sim.drivers.policy.fitted_decision`; the planning driver) decides.
            ``"fitted"`` (default): by that rule, with ``mode`` or not (the planning driver's
            most likely fine acceleration, what its replay fit and pair scores use).
            ``"likelihood-draw"``: the former behaviour, a paper action drawn from (or the mode
            of) the driver's likelihood model ``probs`` and the driver's acceleration within it.
            A driver without a rule (the tabular IRL models, fitted as stochastic policies)
            draws from ``probs`` under either.
        zone_start_ft: B is taken into account once its ``Local_Y`` is at least this (ft);
            None = ``zone_margin_ft`` before the start of the auxiliary lane (from the lane
            shapes of the run).
        zone_margin_ft: see ``zone_start_ft``.
        max_lag_ft: A must be at most this far behind B (ft).
        hold_after_merge_s: keep controlling A this long after B merged (s).
        max_control_s: release A after this long under control (s).
        seed: seed of the action-sampling generator (None: the run's seed).
        safety_ttc_s: the safety-filter variant: None (default) = raw, the
            policy's action is applied as chosen. A number: before applying an action, A's gap
            and time-to-collision to its leader in lane 6 at the end of the decision step are
            predicted (constant accelerations of A, constant speed of the leader); an action
            that would end with the bumper gap below 0 or a closing TTC below this (s) is
            replaced by the nearest harder-braking action that does not (High Brake if none
            does). Interventions are counted per control episode and logged per decision.
        high_brake: how the High Brake action is applied. ``"mean"`` (default, the physical
            actuation): exactly what the driver chose, like every other action: the action's
            acceleration from the model file (the mean of the training data's High Brake bin; a
            planning driver's own acceleration within the bin), capped by A's physical
            deceleration limit (SUMO's ``emergencyDecel``). ``"need"`` (a named variant, like
            the safety filter; it reads the simulator's ground truth, A's true leader and its
            true acceleration, so no driver learned from demonstrations can rely on it): at the
            action's acceleration, or harder when that does not keep A behind its leader in lane 6: the constant
            deceleration that brings A to the leader's speed at A's minimum gap (the leader
            holding its own deceleration), or stops A behind the point where a braking leader
            stops, whichever comes first (:func:`sim.closed_loop.actuation.high_brake_need`),
            at most A's ``decel`` (SUMO's hardest non-emergency braking of A's type, 4.5 m/s^2 =
            14.8 ft/s^2 for the synthetic cars, where over half of the demonstrators' High Brake
            frames sit); how often it braked harder than the driver is counted per control
            episode (``n_need_brakes``). Every commanded driver is actuated alike; which action
            to take stays the driver's.
    """

    decision_step_s: float | None = None
    mode: bool = False
    zone_start_ft: float | None = None
    zone_margin_ft: float = 100.0
    max_lag_ft: float = 250.0
    hold_after_merge_s: float = 3.0
    max_control_s: float = 60.0
    seed: int | None = None
    safety_ttc_s: float | None = None
    high_brake: str = "mean"
    rule: str = "fitted"

    def __post_init__(self) -> None:
        if self.high_brake not in HIGH_BRAKE_RULES:
            raise ControllerError(f"controller.high_brake: must be one of {HIGH_BRAKE_RULES}, got {self.high_brake!r}")
        if self.rule not in DECISION_RULES:
            raise ControllerError(f"controller.rule: must be one of {DECISION_RULES}, got {self.rule!r}")
        for name in ("decision_step_s", "max_lag_ft", "max_control_s", "safety_ttc_s"):
            v = getattr(self, name)
            if v is None and name in ("decision_step_s", "safety_ttc_s"):
                continue
            if not (v > 0 and math.isfinite(v)):
                raise ControllerError(f"controller.{name}: must be a positive number, got {v}")
        if not self.hold_after_merge_s >= 0:
            raise ControllerError(f"controller.hold_after_merge_s: must be >= 0, got {self.hold_after_merge_s}")

    def hold_frames(self, frame_s: float) -> int:
        """``hold_after_merge_s`` in whole frames of ``frame_s`` seconds."""
        return int(round(self.hold_after_merge_s / frame_s))

    def max_frames(self, frame_s: float) -> int:
        """``max_control_s`` in whole frames of ``frame_s`` seconds."""
        return int(round(self.max_control_s / frame_s))

    def zone_start(self, aux_lane_start_ft: float) -> float:
        """``Local_Y`` (ft) from which a B on the ramp is handed a lag car A: ``zone_start_ft``, or
        ``zone_margin_ft`` before ``aux_lane_start_ft`` (:func:`sim.runtime.lanes.aux_lane_start_ft`)."""
        return float(self.zone_start_ft) if self.zone_start_ft is not None else aux_lane_start_ft - self.zone_margin_ft
