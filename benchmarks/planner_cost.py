"""Per-decision cost of the planning driver on one observation (one core), beside the
car-following logit's, and their ratio (target: <= 3 ms per planner decision), under both road
models of the planner (``legacy`` and ``driver``, side by side).

    PYTHONPATH=. OMP_NUM_THREADS=1 python benchmarks/planner_cost.py

Times ``PlanningDriver.act`` (path tensors of the observation, the backup, the softmax, the most
likely fine action: what a controller does per decision) and ``CarFollowingLogit.log_policy``,
the median of repeated calls after warm-up, for each grid and tree (B ahead of A, so the driver
model's safety condition runs for both leaders).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from irl.domains.merge.car_following import CF_FEATURES
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.planning.driver import PlanningDriver
from irl.planning.features import Shape
from irl.planning.model import PlannerConfig

ACC = (-9.5, -2.2, 0.05, 2.3, 6.0)


def per_call_ms(fn: Callable[[], object], repeats: int = 300) -> float:
    """Median wall time of ``fn()`` (ms) over ``repeats`` calls after 20 warm-up calls."""
    for _ in range(20):
        fn()
    ts = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t0
    return float(np.median(ts) * 1e3)


def _act_of(drv: PlanningDriver, obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray) -> Callable[[], object]:
    return lambda: drv.act(obs, prev_acc, acc_C)


def main() -> None:
    rng = np.random.default_rng(0)
    obs = np.array([[120.0, 5.0, 60.0, 3.0, 60.0, 14.8, 14.8]])
    prev, prev_acc, acc_C = np.array([2]), np.array([0.3]), np.array([-1.0])
    cf = CarFollowingLogit(rng.normal(0, 0.5, len(CF_FEATURES)), ACC, 0.3)
    t_cf = per_call_ms(lambda: cf.log_policy(obs, prev))
    print(f"{'driver':58s} {'ms legacy':>9s} {'ms driver':>9s} {'x cf-logit':>10s}")
    print(f"{'cf-logit (CarFollowingLogit.log_policy)':58s} {t_cf:9.3f} {t_cf:9.3f} {1.0:10.1f}")
    for grid, depth, horizon, later in (("g13", 2, 3.0, "bins"), ("g24", 2, 2.1, "bins"), ("g24", 2, 3.9, "bins"),
                                        ("g24", 2, 3.0, "bins+hold"), ("g24", 3, 3.0, "bins")):
        for backup in ("avg", "boltzmann", "softmax"):
            ts = []
            theta = rng.normal(0, 0.5, len(PlannerConfig().feature_names))
            for road in ("legacy", "driver"):
                cfg = PlannerConfig(horizon_s=horizon, depth=depth, backup=backup, grid=grid, later=later,
                                    c_model="ca", road_model=road)
                drv = PlanningDriver(theta, cfg.feature_names, cfg, Shape(), 0.3, ACC)
                ts.append(per_call_ms(_act_of(drv, obs, prev_acc, acc_C)))
            paths = drv.fine_grid.size * (5 + (later == "bins+hold")) ** (depth - 1)
            name = f"planner {grid} {backup} depth={depth} H={horizon}s {later} ({paths} paths)"
            print(f"{name:58s} {ts[0]:9.3f} {ts[1]:9.3f} {ts[1] / t_cf:10.1f}")


if __name__ == "__main__":
    main()
