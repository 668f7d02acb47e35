"""One closed-loop episode: a scenario run with a policy driving the merge lag cars.

:func:`run_episode` is a pure function of its arguments (scenario, policy, seed, settings),
picklable, and meant to run in its own process (libsumo runs one simulation per process at a
time; ``analysis.evaluation.evaluate`` uses a process pool).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.evaluation.metrics import EpisodeMetrics, MetricsConfig, episode_metrics
from merge_irl.cancel import CancelHook
from merge_irl.units import FT_PER_M
from scenarios.loader import load_scenario
from sim.closed_loop.config import ControllerConfig
from sim.closed_loop.controller import Controller
from sim.drivers.policy import Policy
from sim.runtime.hooks import StepHook
from sim.runtime.run import run_scenario
from sim.runtime.sites import site_of


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

    def to_dict(self) -> dict:
        """JSON-serialisable form (the sweep runner stores results as JSON; NaN kept as NaN)."""
        d = {
            "metrics": _plain(self.metrics.to_dict()),
            "controls": frame_to_dict(self.controls),
            "decisions": frame_to_dict(self.decisions),
            "speed_profiles": frame_to_dict(self.speed_profiles),
            "wall_time_s": float(self.wall_time_s),
            "rrd": self.rrd,
        }
        if self.table is not None:
            d["table"] = frame_to_dict(self.table)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> EpisodeResult:
        """Inverse of :meth:`to_dict`."""
        return cls(
            metrics=EpisodeMetrics.from_dict(d["metrics"]), controls=frame_from_dict(d["controls"]),
            decisions=frame_from_dict(d["decisions"]), speed_profiles=frame_from_dict(d["speed_profiles"]),
            wall_time_s=float(d["wall_time_s"]), rrd=str(d.get("rrd", "")),
            table=frame_from_dict(d["table"]) if d.get("table") is not None else None,
        )


def _plain(x):
    """Numpy scalars and containers to plain Python values."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def frame_to_dict(df: pd.DataFrame) -> dict:
    """``{"columns": {name: [values]}, "dtypes": {name: dtype}}`` of a flat DataFrame (index dropped)."""
    return {"columns": {str(c): _plain(df[c].tolist()) for c in df.columns},
            "dtypes": {str(c): str(df[c].dtype) for c in df.columns}}


def frame_from_dict(d: dict) -> pd.DataFrame:
    """Inverse of :func:`frame_to_dict` (same columns, order and dtypes)."""
    cols = d["columns"]
    df = pd.DataFrame({c: pd.Series(v, dtype=object) for c, v in cols.items()}, columns=list(cols))
    return df.astype(d["dtypes"]) if len(cols) else df


@dataclass(frozen=True)
class EpisodeSpec:
    """One closed-loop episode as a sweep task config (see :func:`run_episode_task`).

    Attributes:
        scenario: preset name, TOML path or ScenarioSpec.
        policy: the policy driving the As.
        seed: the episode's SUMO and sampling seed (the same seeds for every policy, so every
            policy meets the same traffic; the sweep's derived seed is not used).
        duration_s, controller, metrics, demo_action_counts, rrd_path, keep_table: as in
            :func:`run_episode` (``demo_action_counts`` as a tuple).
    """

    scenario: object
    policy: Policy
    seed: int
    duration_s: float | None = None
    controller: ControllerConfig = ControllerConfig()
    metrics: MetricsConfig = MetricsConfig()
    demo_action_counts: tuple[int, ...] | None = None
    rrd_path: str | None = None
    keep_table: bool = False


def run_episode_task(spec: EpisodeSpec, seed: int) -> dict:
    """Sweep task: :func:`run_episode` of ``spec`` as ``EpisodeResult.to_dict()``.

    Runs in a sweep worker; a worker runs one task at a time and ``run_scenario`` closes its
    libsumo simulation before returning, so successive episodes in one worker are fine.
    """
    del seed
    counts = None if spec.demo_action_counts is None else np.asarray(spec.demo_action_counts, dtype=np.int64)
    return run_episode(spec.scenario, spec.policy, spec.seed, duration_s=spec.duration_s,
                       controller=spec.controller, metrics=spec.metrics, demo_action_counts=counts,
                       rrd_path=spec.rrd_path, keep_table=spec.keep_table,
                       extra_hooks=(CancelHook(),)).to_dict()  # a Dask task whose sweep stopped: stop here


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
    t0 = time.perf_counter()
    spec = load_scenario(scenario) if isinstance(scenario, (str, Path)) else scenario
    ctl = Controller(policy, controller)
    hooks: list[StepHook] = [ctl]
    if rrd_path is not None:
        # rerun takes about 0.8 s to import: only when recording
        from analysis.recording.log import RerunLogger

        hooks.append(RerunLogger(rrd_path, controller=ctl))
    hooks.extend(extra_hooks)
    res = run_scenario(spec, seed=seed, duration_s=duration_s, hooks=hooks)
    controls = ctl.control_table()
    decisions = ctl.decision_table()
    section = float(res.spec.road.main_length_m) * FT_PER_M
    m = episode_metrics(
        res.table, controls, decisions, policy=policy.name, seed=seed, section_length_ft=section,
        collisions=ctl.n_collisions, teleports=ctl.n_teleports, demo_action_counts=demo_action_counts,
        config=metrics, merge_lane=site_of(res.spec).merge_lane,
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
