"""What the closed-loop controller records: control episodes (:class:`Control`, with the
release reasons and collision kinds they name) and the decision log (:class:`DecisionLog`)."""

from __future__ import annotations

from dataclasses import dataclass, field

RELEASE_REASONS = (
    "merge_done", "left_section", "left_lane", "collision", "teleported", "arrived", "removed", "b_lost",
    "timeout", "end_of_run", "removed_externally",
)


#: Who hit whom in a collision that ended a control (:attr:`Control.collision_kind`): A ran into
#: its lead car C, into the merging car B, or into another vehicle; B or another vehicle (a
#: follower, or a car changing lanes) ran into A.
COLLISION_KINDS = ("A into C", "A into B", "A into other", "B into A", "other into A")


@dataclass
class Control:
    """One control episode of a lag car A for a merging car B (mutable while it runs).

    Attributes:
        a_id, b_id: Vehicle_IDs of A and B; a_sumo: A's SUMO id.
        start_frame: frame of the take-over; end_frame: frame of the release (-1 while active).
        reason: why A was released (one of ``RELEASE_REASONS``; "" while active).
        merge_frame: B's first lane-6 frame (-1 if B had not merged at release).
        b_ahead: at B's merge frame, B's Local_Y > A's (None if B had not merged).
        commanded: whether the policy actually drove A (False for the SUMO baseline).
        gap_AB_start_ft: d_AB at the take-over (ft).
        n_decisions: decisions taken.
        n_interventions: decisions whose action the safety filter replaced.
        n_need_brakes: decisions whose High Brake the ``need`` rule made harder than the
            driver's own (``ControllerConfig.high_brake == "need"``; 0 otherwise).
        prev_action: A's action at the latest decision (-1: none yet).
        prev_acc: the acceleration applied at the latest decision (ft/s^2; NaN: none yet).
        prev_v_c: C's speed at the latest decision (ft/s; NaN: no C), for C's acceleration as
            A sees it (its speed change over one decision).
        max_decel_ft_s2: A's physical deceleration limit (SUMO's ``emergencyDecel``, ft/s^2 > 0;
            NaN until taken over): no commanded acceleration is harder.
        c_id: Vehicle_ID of C at the latest decision (0: none).
        collision_kind: for ``reason == "collision"``, one of ``COLLISION_KINDS``; else "".
        collision_pair: for ``reason == "collision"``, the SUMO ids ``"collider>victim"`` of the
            colliding pair involving A (one of the run's distinct pairs,
            :attr:`sim.closed_loop.controller.Controller.n_collisions`); else "".
    """

    a_id: int
    b_id: int
    a_sumo: str
    start_frame: int
    commanded: bool
    gap_AB_start_ft: float
    end_frame: int = -1
    reason: str = ""
    merge_frame: int = -1
    b_ahead: bool | None = None
    n_decisions: int = 0
    n_interventions: int = 0
    n_need_brakes: int = 0
    prev_action: int = -1
    prev_acc: float = float("nan")
    prev_v_c: float = float("nan")
    max_decel_ft_s2: float = float("nan")
    c_id: int = 0
    collision_kind: str = ""
    collision_pair: str = ""
    speed_mode: int = -1
    lane_change_mode: int = -1
    last_y: float = 0.0

    @property
    def active(self) -> bool:
        return self.end_frame < 0


_DECISION_FIELDS = (
    "frame", "time_s", "a_id", "b_id", "c_id", "state", "action", "acc_cmd", "speed_A",
    "d_AC", "d_AB", "v_AC", "v_AB", "b_is_truck", "len_C", "len_B", "p0", "p1", "p2", "p3", "p4", "filtered",
    "need_brake",
)


@dataclass
class DecisionLog:
    """Column buffers, one row per decision (units ft, ft/s, ft/s^2; ``acc_cmd`` is the
    commanded acceleration (High Brake's can be harder than the action's mean:
    ``ControllerConfig.high_brake``), or for the SUMO baseline A's measured one; ``action`` likewise;
    ``filtered``: the safety filter replaced the policy's action; ``need_brake``: the ``need`` rule
    braked harder than the driver's own High Brake).
    """

    rows: list[tuple] = field(default_factory=list)

    def append(self, row: tuple) -> None:
        self.rows.append(row)

    def to_frame(self):
        import pandas as pd

        if not self.rows:
            return pd.DataFrame({k: pd.Series(dtype="float64") for k in _DECISION_FIELDS})
        return pd.DataFrame(self.rows, columns=list(_DECISION_FIELDS))
