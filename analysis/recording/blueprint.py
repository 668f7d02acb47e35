"""The viewer layout sent with every recording (:func:`merge_blueprint`): the merge view, the
section, car A's time series, the action probabilities and the training tab."""

from __future__ import annotations

from collections.abc import Sequence

from irl.domains.merge.actions import ACTION_NAMES

#: Half extent (ft) of the merge view around the followed car: about 350 ft of road, so that
#: the lanes (12 ft) and the cars (15 ft) are large enough to read in the view.
FOLLOW_HALF_FT = (175.0, 45.0)
#: Bounds of the action-bar view: x over the five bars, y from probability 1 (drawn up) to the names.
ACTION_BARS_BOUNDS = ((-0.6, 4.6), (-1.08, 0.2))
#: TTC axis of the time series (s): larger values are off the chart.
TTC_RANGE_S = (0.0, 10.0)


def merge_blueprint(a_ids: Sequence[int], *, training_methods: Sequence[str] = (),
                    section_bounds: tuple[float, float, float, float] | None = None,
                    first_control: tuple[int, int] | None = None, play: float | None = None,
                    active_tab: int = 0, ttc_ids: Sequence[int] | None = None):
    """The viewer layout of a run's recording (``rerun.blueprint.Blueprint``).

    Tab "run": the merge view (2D, origin ``/follow``: follows the current merge), the whole
    section (2D, origin ``/``), and the group "car A": time series of speed, d_AB, d_AC, TTC
    (y axis clipped to :data:`TTC_RANGE_S`) and the action taken of every controlled car, and
    the current action probabilities as five bars named by action (``policy/action_bars``: rerun's
    bar charts cannot name their bars). Tab "training" (only when
    ``training_methods`` is not empty): log-likelihood and weights against the iteration.
    The time panel shows the ``step`` timeline, paused, with the first take-over selected.
    ``ttc_ids``: the cars with a TTC series (None: all of ``a_ids``).

    Args:
        a_ids: Vehicle_IDs of the controlled cars (their ``metrics/A_<id>`` entities).
        training_methods: the ``<method>`` of the ``train/<method>`` entities.
        section_bounds: ``(x_min, x_max, y_min, y_max)`` ft of the lanes in the mirrored
            frame, the section view's bounds; None: the viewer's own.
        first_control: ``(start_frame, end_frame)`` of the first take-over (Frame_IDs).
        play: play at this speed (x real time) and loop over the selection once the cursor
            reaches it, instead of pausing (for screenshots: the blueprint has no setting for
            the time cursor, which starts at the first frame).
        active_tab: the tab shown first (0 run, 1 training); with the training tab the time
            panel shows the ``iteration`` timeline.
    """
    import rerun.blueprint as rrb
    from rerun.blueprint.components import AbsoluteTimeRange

    def series(name: str, paths: list[str], **kw):
        return rrb.TimeSeriesView(name=name, origin="/", contents=paths or ["-/**"],
                                  plot_legend=rrb.PlotLegend(visible=False), **kw)

    ids = [int(a) for a in a_ids]
    fx, fy = FOLLOW_HALF_FT
    merge = rrb.Spatial2DView(
        name="merge (follows car A)", origin="/follow", contents=["/world/**"],
        visual_bounds=rrb.VisualBounds2D(x_range=(-fx, fx), y_range=(-fy, fy)), background=[30, 30, 30])
    bounds = None
    if section_bounds is not None:
        x0, x1, y0, y1 = section_bounds
        bounds = rrb.VisualBounds2D(x_range=(x0, x1), y_range=(y0, y1))
    section = rrb.Spatial2DView(name="section", origin="/", contents=["/world/**"], background=[30, 30, 30],
                                visual_bounds=bounds)
    car_a = rrb.Vertical(
        series("speed of A (ft/s)", [f"/metrics/A_{a}/speed" for a in ids]),
        series("d_AB (ft)", [f"/metrics/A_{a}/d_AB" for a in ids]),
        series("d_AC (ft)", [f"/metrics/A_{a}/d_AC" for a in ids]),
        series("TTC A to its leader (s)", [f"/metrics/A_{a}/ttc" for a in (ids if ttc_ids is None else ttc_ids)],
               axis_y=rrb.ScalarAxis(range=TTC_RANGE_S, zoom_lock=True)),
        series("action of A (0 " + ACTION_NAMES[0].lower() + " .. 4 " + ACTION_NAMES[-1].lower() + ")",
               [f"/policy/A_{a}/action" for a in ids], axis_y=rrb.ScalarAxis(range=(-0.2, 4.2), zoom_lock=True)),
        rrb.Spatial2DView(name="action probabilities now", origin="/policy/action_bars",
                          contents=["/policy/action_bars/**"], background=[30, 30, 30],
                          visual_bounds=rrb.VisualBounds2D(x_range=ACTION_BARS_BOUNDS[0], y_range=ACTION_BARS_BOUNDS[1])),
        name="car A",
    )
    tabs: list[rrb.Container] = [rrb.Horizontal(rrb.Vertical(merge, section, row_shares=[3, 2]), car_a, column_shares=[3, 2], name="run")]
    if training_methods:
        tabs.append(rrb.Vertical(
            series("log-likelihood", [f"/train/{m}/loglik" for m in training_methods]),
            rrb.TimeSeriesView(name="weights theta", origin="/train", contents=[f"/train/{m}/theta/**" for m in training_methods]),
            name="training"))
    sel = None if first_control is None else AbsoluteTimeRange(min=int(first_control[0]), max=int(first_control[1]))
    return rrb.Blueprint(
        rrb.Tabs(*tabs, active_tab=min(int(active_tab), len(tabs) - 1)),
        rrb.TimePanel(timeline="iteration" if active_tab == 1 and training_methods else "step", state="collapsed",
                      time_selection=sel, play_state="playing" if play and sel is not None else "paused",
                      playback_speed=float(play) if play else None,
                      loop_mode="selection" if play and sel is not None else None),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        auto_views=False,
    )
