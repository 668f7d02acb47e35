"""One closed-loop episode: a scenario run with a policy driving the merge lag cars.

:func:`run_episode` is a pure function of its arguments (scenario, policy, seed, settings),
picklable, and meant to run in its own process (libsumo runs one simulation per process at a
time; ``analysis.evaluate`` uses a process pool).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.metrics import EpisodeMetrics, MetricsConfig, episode_metrics
from sim.controller import Controller, ControllerConfig
from sim.policy import Policy


@dataclass(frozen=True)
class EpisodeResult:
    """What one episode returns (small: no full trajectory table).

    Attributes:
        metrics: the episode's metrics.
        controls: ``Controller.control_table()``.
        decisions: ``Controller.decision_table()``.
        speed_profiles: rows ``a_id, t_s`` (s since take-over), ``v_ft_s`` of A while controlled.
        wall_time_s: seconds for the whole episode.
        rrd: path of the ``.rrd`` written, or "".
        table: the trajectory table if requested (``keep_table``), else None.
    """

    metrics: EpisodeMetrics
    controls: pd.DataFrame
    decisions: pd.DataFrame
    speed_profiles: pd.DataFrame
    wall_time_s: float
    rrd: str = ""
    table: pd.DataFrame | None = field(default=None, repr=False)


def run_episode(
    scenario,
    policy: Policy,
    seed: int,
    *,
    duration_s: float | None = None,
    controller: ControllerConfig = ControllerConfig(),
    metrics: MetricsConfig = MetricsConfig(),
    demo_action_counts: np.ndarray | None = None,
    rrd_path: str | os.PathLike | None = None,
    keep_table: bool = False,
    extra_hooks=(),
) -> EpisodeResult:
    """Simulate ``scenario`` (name, TOML path or ScenarioSpec) with ``policy`` driving the As.

    The controller's action sampling uses ``seed`` too, so the episode is a deterministic
    function of its arguments. ``rrd_path``: also write a rerun recording of the episode.
    """
    import time

    from scenarios.loader import load_scenario
    from sim.run import run_scenario

    t0 = time.perf_counter()
    spec = load_scenario(scenario) if isinstance(scenario, (str, Path)) else scenario
    ctl = Controller(policy, controller)
    hooks = [ctl]
    if rrd_path is not None:
        from analysis.rerun_log import RerunLogger

        hooks.append(RerunLogger(rrd_path, controller=ctl))
    hooks.extend(extra_hooks)
    res = run_scenario(spec, seed=seed, duration_s=duration_s, hooks=hooks)
    controls = ctl.control_table()
    decisions = ctl.decision_table()
    section = float(res.spec.road.main_length_m) / 0.3048
    m = episode_metrics(
        res.table, controls, decisions, policy=policy.name, seed=seed, section_length_ft=section,
        collisions=ctl.n_collisions, teleports=ctl.n_teleports, demo_action_counts=demo_action_counts,
        config=metrics,
    )
    return EpisodeResult(
        metrics=m, controls=controls, decisions=decisions,
        speed_profiles=_speed_profiles(res.table, controls), wall_time_s=time.perf_counter() - t0,
        rrd=str(rrd_path) if rrd_path is not None else "", table=res.table if keep_table else None,
    )


def _speed_profiles(table: pd.DataFrame, controls: pd.DataFrame) -> pd.DataFrame:
    if controls.empty:
        return pd.DataFrame({"a_id": pd.Series(dtype="int64"), "t_s": pd.Series(dtype="float64"),
                             "v_ft_s": pd.Series(dtype="float64")})
    last = int(table["Frame_ID"].max())
    parts = []
    for r in controls.itertuples(index=False):
        end = int(r.end_frame) if int(r.end_frame) >= 0 else last
        sub = table[(table["Vehicle_ID"] == r.a_id) & (table["Frame_ID"] >= r.start_frame) & (table["Frame_ID"] <= end)]
        parts.append(pd.DataFrame({"a_id": int(r.a_id), "t_s": (sub["Frame_ID"].to_numpy() - r.start_frame) * 0.1,
                                   "v_ft_s": sub["v_Vel"].to_numpy()}))
    return pd.concat(parts, ignore_index=True)
