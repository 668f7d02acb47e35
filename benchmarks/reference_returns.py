"""Reference returns of the environment's task reward: what a learner's return compares with.

For each scenario (default ``synthetic`` and ``i80``) and each driver, one episode per evaluation
seed (``reset(seed=s)``: a new SUMO run, its first take-over), the return (the sum of the default
task reward ``"task"`` over the episode, :mod:`sim.env.task_reward`) is recorded; the table gives
its mean and the 95 % interval of the mean (Student's t over the seeds) per driver, with the
mean episode length (decisions of 0.3 s) and the episodes that ended in A's collision. The task
reward is paid per decision, so a return also grows with the episode's length:

* ``zero``: action 2 (Zero, no acceleration) at every decision;
* ``random``: a uniform draw of the five actions (``numpy.random.default_rng(seed)``);
* ``sumo``: SUMO's own driver drives A (the agent's policy does not command A, as the closed
  loop's ``sumo`` baseline; the actions sent are ignored and the reward is of what SUMO did);
* ``planner``: a planning driver file (``--planner``, ``merge-irl learn-driver``'s), its fitted
  acceleration applied as a continuous action (as it drives in the closed loop);
* ``ppo@N``: Stable-Baselines3 PPO (``MlpPolicy``, default settings, ``seed=--ppo-seed``) trained
  for N steps on the scenario (``run_s`` 1800 s runs; ``reset()`` continues a run), then its
  deterministic action. Budgets grow in one model: ``ppo@10240`` continues ``ppo@2048``. PPO
  collects whole rollouts of ``n_steps`` (2048), so a budget is rounded up to a multiple of
  2048: the row names the steps actually trained.

Episodes end at the controller's release or its time limit (``max_control_s``, 200 decisions).
Run: ``python -m benchmarks.reference_returns [--scenarios synthetic i80] [--seeds 0 1 2 3 4 5 6 7]
[--ppo-budgets 2048 10240] [--planner DRIVER.json] [--skip-ppo]``. PPO needs the ``[rl]`` extra.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from merge_irl.units import M_PER_FT

Act = Callable[[np.ndarray], Any]


def run_s_of(scenario: str, extra_s: float) -> float:
    """Simulated seconds of an evaluation run: the scenario's warm-up plus ``extra_s``."""
    from scenarios.loader import load_scenario

    return float(load_scenario(scenario).simulation.warmup_s) + extra_s


def episode_return(env: Any, seed: int, act: Act, reset: Callable[[], None] | None = None
                   ) -> tuple[float, int, bool]:
    """``(return, decisions, collided)`` of the episode ``env.reset(seed=seed)`` starts, ``act(obs)`` choosing."""
    obs, _ = env.reset(seed=seed)
    if reset is not None:
        reset()
    total, n, done, info = 0.0, 0, False, {}
    while not done:
        obs, r, terminated, truncated, info = env.step(act(obs))
        total += float(r)
        n += 1
        done = terminated or truncated or n >= 200
    return total, n, info.get("release_reason") == "collision"


def returns_of(make: Callable[[], Any], seeds: Sequence[int], act: Act,
               reset: Callable[[], None] | None = None) -> list[tuple[float, int, bool]]:
    """``(return, decisions, collided)`` of one episode per seed, in one environment (closed at the end)."""
    env = make()
    try:
        return [episode_return(env, s, act, reset) for s in seeds]
    finally:
        env.close()


def interval(x: Sequence[float]) -> tuple[float, float, float]:
    """``(mean, low, high)``: the mean and its 95 % Student-t interval (nan bounds for one value)."""
    from scipy import stats

    a = np.asarray(x, dtype=np.float64)
    m = float(a.mean())
    if a.size < 2:
        return m, math.nan, math.nan
    h = float(stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return m, m - h, m + h


def baseline_rows(scenario: str, seeds: Sequence[int], run_s: float,
                  planner: str | None) -> dict[str, list[tuple[float, int, bool]]]:
    """The returns of ``zero``, ``random``, ``sumo`` and (with a file) ``planner``."""
    from sim.env import MergeEnv

    def make(**kw: Any) -> Callable[[], Any]:
        return lambda: MergeEnv(scenario, run_s=run_s, **kw)

    rng = np.random.default_rng(0)
    rows = {"zero": returns_of(make(), seeds, lambda o: 2),
            "random": returns_of(make(), seeds, lambda o: int(rng.integers(0, 5)))}

    def sumo_env() -> Any:
        env = MergeEnv(scenario, run_s=run_s)
        # the agent's controller observes A and never commands it: SUMO's car-following drives
        env._core.agent.controls = False
        return env

    rows["sumo"] = returns_of(sumo_env, seeds, lambda o: 2)
    if planner:
        from sim.drivers.formats import policy_callable

        drv = policy_callable(planner)

        def planner_act(o: np.ndarray) -> np.ndarray:
            drv(o)
            return np.array([drv._prev_acc * M_PER_FT], dtype=np.float32)  # its fitted acceleration, m/s^2

        rows["planner"] = returns_of(make(action_type="continuous"), seeds, planner_act, drv.reset)
    return rows


def ppo_rows(scenario: str, seeds: Sequence[int], run_s: float, budgets: Sequence[int],
             ppo_seed: int) -> dict[str, tuple[list[tuple[float, int, bool]], float]]:
    """``ppo@N``: returns and training wall seconds per budget (one model, trained on)."""
    from stable_baselines3 import PPO

    from sim.env import MergeEnv

    out: dict[str, tuple[list[tuple[float, int, bool]], float]] = {}
    model: Any = None
    wall = 0.0
    for budget in sorted(budgets):
        if model is not None and model.num_timesteps >= budget:
            continue  # reached already (a budget rounded up past the next one)
        train = MergeEnv(scenario, run_s=1800.0)
        if model is None:
            model = PPO("MlpPolicy", train, seed=ppo_seed, verbose=0)
        else:
            model.set_env(train)
            model.get_env().seed(ppo_seed + model.num_timesteps)  # the new runs' seeds: fixed, not drawn
        t = time.perf_counter()
        model.learn(total_timesteps=budget - model.num_timesteps, reset_num_timesteps=model.num_timesteps == 0)
        wall += time.perf_counter() - t
        train.close()  # libsumo is free again for the evaluation
        # PPO collects whole rollouts of n_steps (2048): a budget is rounded up to a multiple of it
        out[f"ppo@{model.num_timesteps}"] = (
            returns_of(lambda: MergeEnv(scenario, run_s=run_s), seeds, deterministic(model)), wall)
    return out


def deterministic(model: Any) -> Act:
    """The action of an SB3 ``model`` at ``obs``: its most likely one."""
    return lambda obs: int(model.predict(obs, deterministic=True)[0])


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=["synthetic", "i80"])
    ap.add_argument("--seeds", nargs="+", type=int, default=list(range(8)), help="evaluation seeds, one episode each")
    ap.add_argument("--ppo-budgets", nargs="+", type=int, default=[2048, 10240])
    ap.add_argument("--ppo-seed", type=int, default=0)
    ap.add_argument("--skip-ppo", action="store_true")
    ap.add_argument("--planner", default=None, help="a planning driver file (merge-irl learn-driver)")
    ap.add_argument("--extra-s", type=float, default=120.0,
                    help="simulated seconds of an evaluation run after the scenario's warm-up")
    a = ap.parse_args(argv)
    if any(b <= 0 for b in a.ppo_budgets):
        ap.error(f"--ppo-budgets: every budget must be a positive number of steps, got {a.ppo_budgets}")
    print(f"task-reward return per episode, mean [95% t-interval] over seeds {a.seeds}; PPO seed {a.ppo_seed}")
    print("| scenario | driver | mean return | 95% interval | decisions per episode | collisions | train wall s |")
    print("|---|---|---|---|---|---|---|")
    for scenario in a.scenarios:
        run_s = run_s_of(scenario, a.extra_s)
        t = time.perf_counter()
        for name, (eps, wall) in scenario_rows(scenario, a, run_s).items():
            m, lo, hi = interval([e[0] for e in eps])
            w = f"{wall:.0f}" if math.isfinite(wall) else ""
            print(f"| {scenario} | {name} | {m:.2f} | [{lo:.2f}, {hi:.2f}] | {np.mean([e[1] for e in eps]):.1f} "
                  f"| {sum(e[2] for e in eps)}/{len(eps)} | {w} |", flush=True)
        print(f"<!-- {scenario}: {time.perf_counter() - t:.0f} s wall in all -->", flush=True)


def scenario_rows(scenario: str, a: argparse.Namespace,
                  run_s: float) -> dict[str, tuple[list[tuple[float, int, bool]], float]]:
    """Every driver's episodes on ``scenario`` (and PPO's training wall time; nan for the others)."""
    rows = {k: (v, math.nan) for k, v in baseline_rows(scenario, a.seeds, run_s, a.planner).items()}
    if not a.skip_ppo:
        rows.update(ppo_rows(scenario, a.seeds, run_s, a.ppo_budgets, a.ppo_seed))
    return rows


if __name__ == "__main__":
    main()
