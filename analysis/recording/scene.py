"""The static scene of a rerun recording (:class:`analysis.recording.log.RerunLogger` logs it
when the run starts): the road and its lane centre lines, labelled by role, the landmarks of the
ramp, the vehicle roles' classes and colours, the mirrored ``world`` transform and the action
bars' names. Entities: the module docstring of :mod:`analysis.recording.log`."""

from __future__ import annotations

import numpy as np
import rerun as rr

from irl.domains.merge.actions import ACTION_NAMES
from sim.runtime.hooks import RunContext
from sim.runtime.lanes import aux_lane_start_ft
from sim.runtime.sites import I80, SiteProfile

#: ``class_ids`` of the vehicle boxes, by role.
ROLE_IDS = {"other": 0, "A": 1, "B": 2, "C": 3, "A observed": 4}
#: Short label drawn on a box, by role id ("" = no label).
ROLE_LABELS = ("", "A", "B", "C", "A")
#: RGBA colours of the roles, indexed by role id.
ROLE_COLORS = np.array(
    [[150, 150, 150, 255], [230, 40, 40, 255], [40, 110, 230, 255], [40, 180, 70, 255], [240, 150, 30, 255]],
    dtype=np.uint8,
)
ROLE_RGBA_U32 = (ROLE_COLORS.astype(np.uint32) @ np.array([1 << 24, 1 << 16, 1 << 8, 1], dtype=np.uint32)).astype(np.uint32)
#: The ``world`` transform: y mirrored (2D views draw y downwards).
MIRROR_Y = np.diag([1.0, -1.0, 1.0])
#: RGBA of the road surface and of the lane centre lines.
ROAD_RGBA = (62, 62, 66, 255)
LANE_LINE_RGBA = (150, 150, 150, 255)


def lane_roles(site: SiteProfile) -> dict[str, str]:
    """What each lane of ``site`` is, for its label, by lane code (other lanes are "lane <n>"):
    the merge lane "right main lane", a ramp lane "ramp / auxiliary lane" (or "ramp" when the site
    has auxiliary lanes of their own, each "auxiliary lane")."""
    roles = {str(site.merge_lane): "right main lane"}
    for lane in site.ramp_lanes:
        roles[str(lane)] = "ramp" if site.auxiliary_lanes else "ramp / auxiliary lane"
    for lane in site.auxiliary_lanes:
        roles[str(lane)] = "auxiliary lane"
    return roles


#: :func:`lane_roles` of I-80 (and of every preset): lane 6 the right main lane, 7 the ramp.
LANE_ROLES = lane_roles(I80)


def road_landmarks(ctx: RunContext) -> tuple[np.ndarray, list[str]]:
    """``[m, 2]`` positions (ft, SUMO's frame) and labels of the road's landmarks: where the
    ramp lane of the run's site (``ctx.site``; I-80: 7) begins, where it first runs beside the
    merge lane (I-80: 6; the auxiliary lane, the merge zone) and where it ends. Empty when the
    run has no ramp lane or no merge lane."""
    ramp, merge = str(ctx.site.ramp_lanes[0]), str(ctx.site.merge_lane)
    if ramp not in ctx.lane_shapes or merge not in ctx.lane_shapes:
        return np.zeros((0, 2)), []
    l6 = np.asarray(ctx.lane_shapes[merge], dtype=np.float64)[:, :2]
    l7 = np.asarray(ctx.lane_shapes[ramp], dtype=np.float64)[:, :2]
    x_aux = float(l6[0, 0]) + aux_lane_start_ft(ctx)
    aux = np.array([x_aux, float(np.interp(x_aux, l7[:, 0], l7[:, 1]))])
    return np.stack([l7[0], aux, l7[-1]]), ["on-ramp", "merge zone: auxiliary lane begins", "auxiliary lane ends"]


def log_scene(rec: rr.RecordingStream, ctx: RunContext) -> tuple[tuple[float, float, float, float], np.ndarray] | None:
    """Log the static scene of the run ``ctx`` to ``rec``. Returns the section's bounds
    ``(x_min, x_max, y_min, y_max)`` (ft, mirrored frame, 30 ft around the lanes) and its centre,
    where the "merge" view looks before the first take-over; None without lane shapes."""
    names = sorted(ctx.lane_shapes, key=lambda s: int(s) if s.isdigit() else 99)
    strips = [np.asarray(ctx.lane_shapes[n], float)[:, :2] for n in names]
    half_lane = 0.5 * float(ctx.lane_width_ft)
    rec.log("world/road", rr.LineStrips2D(strips, radii=half_lane, draw_order=0.0,
                                          colors=[ROAD_RGBA] * len(strips)), static=True)
    roles = lane_roles(ctx.site)
    labels = [f"lane {n}" + (f" ({roles[n]})" if n in roles else "") for n in names]
    rec.log("world/lanes", rr.LineStrips2D(strips, labels=labels, draw_order=10.0, show_labels=True,
                                           radii=rr.Radius.ui_points(1.0),
                                           colors=[LANE_LINE_RGBA] * len(strips)), static=True)
    marks, mark_labels = road_landmarks(ctx)
    if mark_labels:
        rec.log("world/landmarks", rr.Points2D(marks, labels=mark_labels, show_labels=True, radii=4.0,
                                               colors=[(255, 220, 80, 255)] * len(mark_labels), draw_order=20.0),
                static=True)
    rec.log("policy/action_bars/names", rr.Points2D(
        np.stack([np.arange(len(ACTION_NAMES), dtype=np.float64), np.full(len(ACTION_NAMES), 0.08)], axis=1),
        labels=[n.lower() for n in ACTION_NAMES], show_labels=True, radii=0.001,
        colors=[(220, 220, 220, 255)] * len(ACTION_NAMES)), static=True)
    rec.log("world", rr.AnnotationContext(
        [(i, name, tuple(int(c) for c in ROLE_COLORS[i][:3])) for name, i in ROLE_IDS.items()]), static=True)
    rec.log("world", rr.Transform3D(mat3x3=MIRROR_Y), static=True)
    if strips:
        pts = np.concatenate(strips) @ MIRROR_Y[:2, :2]
        lo, hi = pts.min(axis=0) - 30.0, pts.max(axis=0) + 30.0
        return (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])), 0.5 * (lo + hi)
    return None
