"""Reward features of one predicted step of the planning driver, and their shape fit.

The reward is linear, ``r(s, a, a_prev) = theta . phi(s', a, a_prev)`` (learned ``theta``), plus
a fixed collision penalty (:attr:`~irl.planning.model.PlannerConfig.collision_penalty`,
not learned). Units: ft, ft/s, ft/s^2, s. A step is one decision step in which A holds one
acceleration ``a``; state features are scored on the state the step ends in, action features
on ``a`` and the acceleration held before it (``a_prev``, continuous):

========================  ==================================================================
``gap_need_C``            ``min((s*/s)^2, clip_need)``, the interaction term of the Intelligent
                          Driver Model (IDM; Treiber, Hennecke & Helbing 2000, Phys. Rev. E 62,
                          1805) towards C: ``s`` the bumper gap (at least 1 ft),
                          ``s* = s0 + max(0, v_A T + v_A dv / (2 sqrt(a b)))``, ``dv = v_A - v_C``;
                          0 without C.
``gap_need_B``            the same towards B while B is a leader (ahead of A at the
                          observation, ``d_AB > 0``, and still predicted ahead), else 0.
``inv_ttc_C`` / ``_B``    ``min(max(dv, 0) / s, clip_ittc)`` (1/s); 0 without the leader.
``headway_C`` / ``_B``    ``exp(-THW / T)``, ``THW = max(s, 0) / max(v_A, 0.1)`` (s).
``gap_track_C`` / ``_B``  ``min(((s - s_d) / s_d)^2, CLIP_TRACK)``, ``s_d = s0 + v_A T`` the desired
                          gap (constant time headway ``T``, standstill gap ``s0``): symmetric, so
                          falling behind costs as well as closing in (the terms above only
                          punish closing in); 0 without the leader. Optional (``gap_track``).
``speed_gain``            ``v_A / v0``; ``speed_dev``: ``(v_A / v0 - 1)^2``.
``free_road``             ``(v_A / v0)^4``, IDM's free-road term (optional, ``free_road``).
``comfort``               ``(a / 8)^2``.
``jerk``                  ``((a - a_prev) / 8)^2``, ``a_prev`` continuous: persistence as a
                          smooth cost, so the best acceleration relaxes from ``a_prev`` towards
                          what the state asks for (a binary keep-action feature on 5 coarse bins
                          never lets the driver leave its bin; see docs of the driver).
                          Optional (``jerk``): without it the reward has no action history
                          (persistence may instead be an actuation lag, see
                          :attr:`~irl.planning.model.PlannerConfig.lag`).
``bias_<action>``         one-hot of the paper action (bin) of ``a`` (Zero is the reference;
                          optional).
========================  ==================================================================

A collision (legacy road model) is a bumper gap ``<= 0`` to C (the leader in A's lane); B, the
merging car in the next lane, is no collision partner. The driver's road model
(:attr:`~irl.planning.model.PlannerConfig.road_model`) also counts B ahead of A, a gap below a
margin while it closes, and a first action after which A, braking at its emergency deceleration,
could not stay behind a leader braking hard (:func:`min_gap_braking`, :func:`closing_margin`).

**Shape fit** (:func:`fit_shape`): ``v0`` a high quantile of A's speed; ``s0, T, b`` by a robust
least-squares fit of IDM's acceleration to the demonstrated ones. IDM's maximum acceleration
``a`` is *not* fitted but held at SUMO's passenger-car 2.6 m/s^2: fitted freely on 0.3 s
decisions it ran to its lower bound on both synthetic and real data (mostly near-zero human
accelerations pull the overall scale down), and in the features it only appears in the product
``a b`` that ``b`` already carries.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import least_squares

from irl.domains.merge.actions import N_ACTIONS, ZERO_ACTION, actions_of
from irl.domains.merge.features import BIAS_FEATURES
from irl.errors import ConfigError
from merge_irl.units import FT_PER_M

#: Acceleration scale of the action features (ft/s^2), as in the car-following logit.
ACC_SCALE_FT_S2 = 8.0
#: Length (ft) of a leader whose length is unknown (NaN): a 4.5 m car.
DEFAULT_LENGTH_FT = 4.5 * FT_PER_M

STATE_FEATURES = ("gap_need_C", "gap_need_B", "inv_ttc_C", "inv_ttc_B", "headway_C", "headway_B",
                  "speed_gain", "speed_dev")
#: The symmetric gap-tracking features (optional, ``gap_track``).
TRACK_FEATURES = ("gap_track_C", "gap_track_B")
#: Bound of the gap-tracking features: a gap 3x the desired one (or a collision) costs no more.
CLIP_TRACK = 4.0
ACTION_FEATURES = ("comfort", "jerk")
#: Paper actions of the bias features, in :data:`BIAS_FEATURES` order (Zero has none).
BIAS_ACTIONS = tuple(a for a in range(N_ACTIONS) if a != ZERO_ACTION)


def feature_names(with_bias: bool, jerk: bool = True, free_road: bool = False,
                  gap_track: bool = False) -> tuple[str, ...]:
    """The ``K`` learned feature names, in the order of the feature axis."""
    return (STATE_FEATURES + (TRACK_FEATURES if gap_track else ()) + (("free_road",) if free_road else ())
            + ("comfort",) + (("jerk",) if jerk else ()) + (BIAS_FEATURES if with_bias else ()))


@dataclass(frozen=True)
class Shape:
    """Shape parameters of the features (ft, s, ft/s^2, ft/s), fitted by :func:`fit_shape`.

    Defaults: SUMO's passenger car (minGap 2.5 m, tau 1 s, accel 2.6, decel 4.5 m/s^2, 29 m/s).
    ``clip_need`` bounds ``(s*/s)^2``, ``clip_ittc`` the inverse TTC (1/s).

    Raises:
        ConfigError: a parameter not finite and positive (``s0_ft`` may be 0).
    """

    s0_ft: float = 2.5 * FT_PER_M
    T_s: float = 1.0
    a_ft_s2: float = 2.6 * FT_PER_M
    b_ft_s2: float = 4.5 * FT_PER_M
    v0_ft_s: float = 29.0 * FT_PER_M
    clip_need: float = 25.0
    clip_ittc: float = 5.0

    def __post_init__(self) -> None:
        bad = {k: v for k, v in asdict(self).items()
               if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
               or not (v > 0 or (k == "s0_ft" and v == 0))}
        if bad:
            raise ConfigError(f"Shape: parameters must be finite and positive, got {bad}")

    def as_dict(self) -> dict[str, float]:
        """The fields as a JSON-ready dict."""
        return {k: float(v) for k, v in asdict(self).items()}


def leader_features(s: np.ndarray, v_a: np.ndarray, dv: np.ndarray, present: np.ndarray,
                    shape: Shape, kinds: tuple[str, ...] = ("gap_need", "inv_ttc", "headway")) -> tuple[np.ndarray, ...]:
    """(gap need, inverse TTC, headway) towards one leader, or those of ``kinds`` in that
    order; 0 where ``present`` is False.

    Args:
        s: bumper gap (ft); v_a: A's speed (ft/s); dv: closing speed ``v_A - v_leader`` (ft/s);
        present: bool, the leader counts; all broadcast to one shape.
    """
    s_safe = np.where(present, s, 1e6)
    dv = np.where(present, dv, 0.0)
    z = np.zeros(())
    out = []
    if "gap_need" in kinds:
        s_star = shape.s0_ft + np.maximum(
            v_a * shape.T_s + v_a * dv / (2.0 * math.sqrt(shape.a_ft_s2 * shape.b_ft_s2)), 0.0)
        out.append(np.where(present, np.minimum((s_star / np.maximum(s_safe, 1.0)) ** 2, shape.clip_need), z))
    if "inv_ttc" in kinds:
        out.append(np.where(present, np.minimum(np.maximum(dv, 0.0) / np.maximum(s_safe, 1.0), shape.clip_ittc), z))
    if "headway" in kinds:
        out.append(np.where(present, np.exp(-np.maximum(s_safe, 0.0) / np.maximum(v_a, 0.1) / shape.T_s), z))
    return tuple(out)


def gap_track(s: np.ndarray, v_a: np.ndarray, present: np.ndarray, shape: Shape) -> np.ndarray:
    """``min(((s - s_d) / s_d)^2, CLIP_TRACK)``, ``s_d = s0 + v_A T`` (at least 1 ft); 0 where
    ``present`` is False (module docstring). ``s`` bumper gap (ft), ``v_a`` A's speed (ft/s)."""
    s_d = np.maximum(shape.s0_ft + v_a * shape.T_s, 1.0)
    track = np.minimum(((np.where(present, s, s_d) - s_d) / s_d) ** 2, CLIP_TRACK)
    return np.where(present, track, 0.0)


def fit_shape(gap_C_ft: np.ndarray, v_A: np.ndarray, dv_C: np.ndarray, acc_ft_s2: np.ndarray, *,
              v0_quantile: float = 0.95, max_gap_ft: float = 300.0) -> Shape:
    """Fit the feature shape on demonstrated decisions (deterministic; module docstring).

    ``v0``: the ``v0_quantile`` quantile of the finite ``v_A`` (at least 10 ft/s). ``s0, T, b``:
    scipy's robust least squares (``soft_l1``, scale 2 ft/s^2, trust-region reflective, from
    SUMO's passenger-car values; bounds ``s0`` 0-40 ft, ``T`` 0.2-3 s, ``b`` 2-30 ft/s^2) of
    ``a (1 - (v/v0)^4 - (s*/s)^2)`` with ``a`` fixed, against the accelerations of the decisions
    with C at a bumper gap in ``(0, max_gap_ft)``; fewer than 20 such decisions: the defaults.

    Args:
        gap_C_ft, v_A, dv_C, acc_ft_s2: ``[N]`` bumper gap to C (NaN without C), A's speed,
            closing speed to C (ft/s) and A's acceleration over the decision (ft/s^2).

    Raises:
        ConfigError: no finite speed of A.
    """
    v_A = np.asarray(v_A, dtype=np.float64)
    gap, dv, acc = (np.asarray(x, dtype=np.float64) for x in (gap_C_ft, dv_C, acc_ft_s2))
    fin = np.isfinite(v_A)
    if not fin.any():
        raise ConfigError("fit_shape: no finite speed of A")
    v0 = max(float(np.quantile(v_A[fin], v0_quantile)), 10.0)
    sel = fin & np.isfinite(gap) & np.isfinite(dv) & np.isfinite(acc) & (gap > 0) & (gap < max_gap_ft)
    d = Shape()
    if sel.sum() < 20:
        return Shape(v0_ft_s=v0)
    s, v, dvs, a_obs = gap[sel], v_A[sel], dv[sel], acc[sel]
    a = d.a_ft_s2

    def resid(p: np.ndarray) -> np.ndarray:
        s0, T, b = p
        s_star = s0 + np.maximum(v * T + v * dvs / (2.0 * np.sqrt(a * b)), 0.0)
        return a * (1.0 - (v / v0) ** 4 - (s_star / np.maximum(s, 1.0)) ** 2) - a_obs

    res = least_squares(resid, np.array([d.s0_ft, d.T_s, d.b_ft_s2]), loss="soft_l1", f_scale=2.0,
                        bounds=([0.0, 0.2, 2.0], [40.0, 3.0, 30.0]), method="trf")
    s0, T, b = (float(x) for x in res.x)
    return Shape(s0_ft=s0, T_s=T, b_ft_s2=b, v0_ft_s=v0)


def step_features(s_C: np.ndarray, v_C: np.ndarray, has_C: np.ndarray, s_B: np.ndarray, v_B: np.ndarray,
                  B_lead: np.ndarray, v_A: np.ndarray, acc: np.ndarray, acc_prev: np.ndarray, shape: Shape,
                  with_bias: bool, jerk: bool = True, free_road: bool = False, track: bool = False,
                  need: frozenset[str] | None = None) -> np.ndarray:
    """``[..., K]`` features of one step (module docstring); the inputs broadcast to ``[...]``:
    the step's end state (bumper gaps ``s_C``, ``s_B`` ft; speeds ft/s; ``has_C``, ``B_lead``
    bool) and the step's and the previous accelerations (ft/s^2). ``need``: only these features
    are computed, the others left 0 (a driver acting needs only its nonzero weights' features;
    a leader absent everywhere costs nothing); None: all."""
    shp = np.broadcast_shapes(*(np.shape(x) for x in (s_C, v_C, s_B, v_A, acc, acc_prev)))
    names = feature_names(with_bias, jerk, free_road, track)
    col = {n: j for j, n in enumerate(names)}
    want = set(names) if need is None else set(need) & set(names)
    out = np.empty(shp + (len(names),)) if need is None else np.zeros(shp + (len(names),))
    for who, s, v, present in (("C", s_C, v_C, has_C), ("B", s_B, v_B, B_lead)):
        kinds = [k for k in ("gap_need", "inv_ttc", "headway") if f"{k}_{who}" in want]
        if kinds and (need is None or np.any(present)):
            for k, x in zip(kinds, leader_features(s, v_A, v_A - v, present, shape, tuple(kinds))):
                out[..., col[f"{k}_{who}"]] = x
        if f"gap_track_{who}" in want and (need is None or np.any(present)):
            out[..., col[f"gap_track_{who}"]] = gap_track(s, v_A, present, shape)
    vr = v_A / shape.v0_ft_s
    if "speed_gain" in want:
        out[..., col["speed_gain"]] = vr
    if "speed_dev" in want:
        out[..., col["speed_dev"]] = (vr - 1.0) ** 2
    if "free_road" in want:
        out[..., col["free_road"]] = vr ** 4
    if "comfort" in want:
        out[..., col["comfort"]] = (acc / ACC_SCALE_FT_S2) ** 2
    if "jerk" in want:
        out[..., col["jerk"]] = ((acc - acc_prev) / ACC_SCALE_FT_S2) ** 2
    if with_bias and any(b in want for b in BIAS_FEATURES):
        bins = actions_of(acc)
        for j, a in enumerate(BIAS_ACTIONS):
            out[..., col[BIAS_FEATURES[j]]] = bins == a
    return out


def collision(s_C: np.ndarray, has_C: np.ndarray) -> np.ndarray:
    """bool, the broadcast shape: the step ends in a collision with C (bumper gap ``<= 0``)."""
    return has_C & (s_C <= 0.0)


def closing_margin(s: np.ndarray, v_a: np.ndarray, v_l: np.ndarray, present: np.ndarray,
                   margin_ft: float) -> np.ndarray:
    """bool, the broadcast shape: a bumper gap ``s`` (ft) to a ``present`` leader ``<= 0``, or
    below ``margin_ft`` while A (speed ``v_a``) is faster than the leader (``v_l``, ft/s): a small
    gap that opens costs nothing."""
    return present & ((s <= 0.0) | ((s < margin_ft) & (v_a > v_l)))


def min_gap_braking(gap: np.ndarray, v_f: np.ndarray, v_l: np.ndarray, b_f: np.ndarray | float,
                    b_l: np.ndarray | float) -> np.ndarray:
    """The smallest bumper gap (ft) over ``t >= 0`` when a follower at speed ``v_f`` brakes at
    ``b_f > 0`` and its leader at ``v_l`` brakes at ``b_l > 0`` (ft/s, ft/s^2), each until it
    stops, from the bumper gap ``gap``; closed form, broadcast over the inputs.

    The gap is piecewise quadratic in ``t``, with kinks where either car stops; while both move
    it has a stationary point where the speeds are equal (a minimum when ``b_f > b_l``), and once
    one has stopped it is monotone. Its minimum is therefore the least of its values at 0, at the
    equal-speed time (clipped into the phase where both move) and at both stopping times
    (the safe-distance condition of Gipps 1981, Transp. Res. B 15, 105, without its
    approximations).
    """
    v_f, v_l = np.maximum(v_f, 0.0), np.maximum(v_l, 0.0)
    t_f, t_l = v_f / b_f, v_l / b_l
    db = np.asarray(b_f - b_l, dtype=np.float64)
    t_eq = np.where(db > 0, np.maximum(v_f - v_l, 0.0) / np.where(db > 0, db, 1.0), 0.0)
    t_eq = np.minimum(t_eq, np.minimum(t_f, t_l))

    def at(t: np.ndarray) -> np.ndarray:
        tf, tl = np.minimum(t, t_f), np.minimum(t, t_l)
        return gap + (v_l * tl - 0.5 * b_l * tl * tl) - (v_f * tf - 0.5 * b_f * tf * tf)

    return np.minimum(np.minimum(gap, at(t_eq)), np.minimum(at(t_f), at(t_l)))
