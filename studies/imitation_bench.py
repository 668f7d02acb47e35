"""Study: the ``imitation`` library's learners beside ours, in the same closed loop.

One run, side by side, on the demo's synthetic demonstrations (:func:`analysis.demo.pipeline.run_demo`:
training runs ``--train-seeds``, ``--heldout-runs`` held-out runs from seed 201; or ``--demo`` a
folder an earlier run left):

* **ours**: Q-Avg (tabular IRL), the car-following logit ``cf-logit`` (the demonstrations alone)
  and the planning driver ``planner``, as the demo learns them;
* **imitation 1.0.1**: behaviour cloning (``imitation.algorithms.bc.BC``, its default
  32x32 actor, ``--bc-epochs`` epochs) and GAIL (``imitation.algorithms.adversarial.gail.GAIL``,
  a small Stable-Baselines3 PPO generator, ``--gail-steps`` environment steps on
  ``MergeIRL/OnRampMerge-v0``), both on the same training encounters as ours, as transitions
  (:func:`sim.merges.transitions.from_encounters`, the decisions Q-Avg learns from, made
  ``imitation`` Trajectories by :func:`sim.merges.transitions.to_imitation_trajectories`): the policy
  observation (:func:`sim.drivers.observe.policy_rows`, ft and ft/s; the networks standardise it in
  their first layer, :class:`studies.imitation_nets.Standardize`) and the discrete merge
  action 0..4. Unlike Q-Avg's and cf-logit's, their observation holds no previous action. Each
  drives twice: the Stable-Baselines3 policy itself by its most likely action (``imit-bc``,
  ``imit-gail``; ``predict(deterministic=True)``) and an action sampled from its probabilities
  (``imit-bc-sampled``, ``imit-gail-sampled``, as the controller samples our drivers');
* **trivial baselines**: uniform, marginal, markov, bc (tabular, the paper state) and SUMO's
  own driver (``sumo``; ``sumo-in-lane``: A's lane changes off while observed, the
  demonstrators' driver).

Every policy drives car A of every merge in seeds ``--seed .. --seed + --episodes - 1`` through
:func:`analysis.evaluation.evaluate.evaluate` (the imitation policies through
:class:`sim.drivers.callables.CallablePolicy`; every action applied at the training data's mean
acceleration of its bin, as the fitted baselines'). Printed: the training wall time, A
collisions with the Wilson 95 % interval, the held-out log-likelihood per decision (the
evaluation's own for ours and the baselines; for BC and GAIL the actor's probabilities of the
held-out transitions at 0.3 s, the decisions the tabular drivers are scored on; shown on the
sampled rows, whose driving those probabilities are), and the Wasserstein-1
distances of the evaluation (TTC to C, A's speed, A's acceleration, d_AC) to the held-out
demonstrations. Before the table: GAIL's log, first round and last (:func:`gail_log_summary`:
PPO's entropy and approximate KL, the discriminator's loss and accuracy, the episode length),
and each sampled actor's mean entropy on the held-out decisions (uniform: log 5 = 1.609 nats).
GAIL's settings are :class:`GailConfig`'s (32,768 steps: docs/imitation.md, "GAIL's budget",
and :mod:`studies.gail_diagnosis`).

Torch and imitation are imported inside the functions that use them (the ``imitation-bench``
extra); ``--help`` and the helpers without torch run in the default install. Deterministic where
the libraries allow: ``torch.manual_seed``, one torch thread, ``numpy`` Generators and
Stable-Baselines3 seeds from ``--train-seed``.

Run::

    pip install torch==2.13.0            # its CPU build first (docs/imitation.md)
    pip install -e ".[imitation-bench]"
    python -m studies.imitation_bench --episodes 10 --out runs/imitation-bench-full
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
from sim.merges.transitions import Transitions, to_imitation_trajectories
from studies.support.gail_config import GailConfig, gail_log_summary
from studies.support.obs_scaler import ObsScaler

#: The evaluation's trivial baselines, in the table's order.
BASELINES = ("uniform", "marginal", "markov", "bc", "sumo", "sumo-in-lane")


def _f(x: float | None, nd: int = 3) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


# -- the imitation policies as callables -------------------------------------------------------
class TorchActor:
    """A Stable-Baselines3 actor-critic policy (BC's, PPO's) as a callable ``obs [7] -> action``
    for :class:`sim.drivers.callables.CallablePolicy`, sampling the action from the actor's
    probabilities with a ``numpy`` Generator seeded ``seed`` (each evaluation episode unpickles
    a fresh copy, so every episode starts the same stream); ``sample=False``: the most likely
    action, as the policy's own ``predict(obs, deterministic=True)``. ``obs``: the policy
    observation (:func:`sim.drivers.observe.policy_rows`). Picklable (the evaluation's worker
    processes); one torch thread per process.
    """

    def __init__(self, policy: Any, *, sample: bool = True, seed: int = 0):
        self.policy, self.sample, self.seed = policy, sample, seed
        self._rng = np.random.default_rng(seed)

    def __getstate__(self) -> dict:
        return {"policy": self.policy, "sample": self.sample, "seed": self.seed}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["policy"], sample=state["sample"], seed=state["seed"])  # type: ignore[misc]

    def probs(self, obs: np.ndarray) -> np.ndarray:
        """``[N, 5]`` action probabilities of ``[N, 7]`` policy observations."""
        import torch

        if torch.get_num_threads() != 1:
            torch.set_num_threads(1)
        x = torch.as_tensor(np.atleast_2d(np.asarray(obs, dtype=np.float32)))
        with torch.no_grad():
            p = self.policy.get_distribution(x).distribution.probs
        return p.numpy().astype(np.float64)

    def __call__(self, obs: np.ndarray) -> int:
        p = self.probs(obs)[0]
        if not self.sample:
            return int(np.argmax(p))
        return int(min(np.searchsorted(np.cumsum(p), self._rng.random() * p.sum(), side="right"), N_ACTIONS - 1))


def heldout_loglik(actor: TorchActor, held: Transitions) -> tuple[float, float]:
    """``(sum, per decision)`` log-likelihood (nats) of the held-out decisions ``held`` (their
    ``[N, 7]`` policy observations and ``[N]`` actions) under ``actor``'s probabilities."""
    p = actor.probs(held.policy_obs())[np.arange(held.n), held.acts]
    with np.errstate(divide="ignore"):
        lp = np.log(p)
    return float(lp.sum()), float(lp.mean())


def mean_entropy(actor: TorchActor, obs: np.ndarray) -> float:
    """Mean entropy (nats) of ``actor``'s action probabilities over ``[N, 7]`` policy
    observations (uniform over the 5 actions: log 5 = 1.609)."""
    p = actor.probs(obs)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -np.where(p > 0, p * np.log(p), 0.0).sum(axis=1)
    return float(h.mean())


# -- training ----------------------------------------------------------------------------------
def seed_torch(seed: int) -> None:
    """Seed torch, one thread, deterministic algorithms where torch has them."""
    import torch

    torch.manual_seed(seed)
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True, warn_only=True)


def observation_space() -> Any:
    """The environment's observation space (:class:`sim.env.merge_env.MergeEnv`'s ``Box``)."""
    import gymnasium as gym

    from sim.drivers.observe import POLICY_OBS_HIGH, POLICY_OBS_LOW

    return gym.spaces.Box(POLICY_OBS_LOW, POLICY_OBS_HIGH, dtype=np.float64)


def extractor_kwargs(scaler: ObsScaler) -> dict[str, Any]:
    """Stable-Baselines3 policy keywords: the :class:`~studies.imitation_nets.Standardize` first layer."""
    from studies.imitation_nets import Standardize

    return {"features_extractor_class": Standardize,
            "features_extractor_kwargs": {"mean": scaler.mean, "std": scaler.std}}


def train_bc(demos: list[Any], scaler: ObsScaler, *, seed: int, epochs: int, log_dir: Path,
             batch_size: int = 64) -> tuple[Any, float]:
    """imitation's behaviour cloning on ``demos`` (:func:`sim.merges.transitions.to_imitation_trajectories`):
    its default 32x32 actor (``FeedForward32Policy``) behind a standardising first layer, its
    log as CSV in ``log_dir``; returns ``(policy, wall seconds)``."""
    import gymnasium as gym
    import torch
    from imitation.algorithms import bc
    from imitation.policies.base import FeedForward32Policy
    from imitation.util import logger as imit_logger

    seed_torch(seed)
    t0 = time.perf_counter()
    space, actions = observation_space(), gym.spaces.Discrete(N_ACTIONS)
    policy = FeedForward32Policy(observation_space=space, action_space=actions,
                                 lr_schedule=lambda _: torch.finfo(torch.float32).max, **extractor_kwargs(scaler))
    trainer = bc.BC(observation_space=space, action_space=actions, policy=policy, demonstrations=demos,
                    rng=np.random.default_rng(seed), batch_size=batch_size, device="cpu",
                    custom_logger=imit_logger.configure(log_dir, ["csv"]))
    trainer.train(n_epochs=epochs, progress_bar=False, log_interval=10**9)
    return trainer.policy, time.perf_counter() - t0


class ZeroReward:
    """The environment's reward for GAIL, which learns its own: 0 for every decision. It carries
    the training data's per-action accelerations (``action_acc_ft_s2``, ft/s^2), which
    :class:`sim.env.merge_env.MergeEnv` applies for the discrete actions, as the evaluation
    applies them."""

    def __init__(self, action_acc_ft_s2: tuple[float, ...]):
        self.action_acc_ft_s2 = tuple(float(a) for a in action_acc_ft_s2)

    def __call__(self, obs: Any, action_bin: int, acc_ft_s2: float) -> float:
        return 0.0


def make_gail(demos: list[Any], scaler: ObsScaler, action_acc_ft_s2: tuple[float, ...], *,
              seed: int, config: GailConfig, env_seed: int, log_dir: Path, scenario: str = "synthetic") -> Any:
    """imitation's GAIL trainer on ``demos`` (:func:`sim.merges.transitions.to_imitation_trajectories`),
    untrained: a PPO generator (32x32 actor and critic behind a standardising first layer) on
    ``MergeIRL/OnRampMerge-v0`` (discrete actions at ``action_acc_ft_s2``, reward 0, SUMO seed
    ``env_seed`` for its first run; a Stable-Baselines3 ``Monitor``, so its log has the episode
    lengths); the discriminator :class:`imitation.rewards.reward_nets.BasicRewardNet` on
    (observation, action) with a running input normalisation; both as ``config`` sets them
    (``config.steps`` unused here). Logs as CSV in ``log_dir``. Torch seeded ``seed``; the caller
    trains it (``.train(steps)``) and closes ``.venv_train``."""
    import gymnasium as gym
    from imitation.algorithms.adversarial.gail import GAIL
    from imitation.rewards.reward_nets import BasicRewardNet
    from imitation.util import logger as imit_logger
    from imitation.util.networks import RunningNorm
    from stable_baselines3 import PPO
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from sim.env import ENV_ID

    seed_torch(seed)
    venv = DummyVecEnv([lambda: Monitor(gym.make(ENV_ID, scenario=scenario, reward=ZeroReward(action_acc_ft_s2)))])
    n_steps = config.n_steps
    learner = PPO("MlpPolicy", venv, n_steps=n_steps, batch_size=min(config.batch_size, n_steps),
                  n_epochs=config.n_epochs, learning_rate=config.learning_rate, ent_coef=config.ent_coef,
                  gamma=config.gamma, seed=seed, device="cpu",
                  policy_kwargs={"net_arch": [32, 32], **extractor_kwargs(scaler)})
    venv.seed(env_seed)  # after PPO's own seeding, which seeds the environment with the PPO seed
    reward_net = BasicRewardNet(venv.observation_space, venv.action_space, normalize_input_layer=RunningNorm)
    log_dir.mkdir(parents=True, exist_ok=True)
    return GAIL(demonstrations=demos, demo_batch_size=config.demo_batch_size, venv=venv, gen_algo=learner,
                reward_net=reward_net, n_disc_updates_per_round=config.disc_updates,
                disc_opt_kwargs={"lr": config.disc_lr}, gen_replay_buffer_capacity=n_steps,
                allow_variable_horizon=True, log_dir=log_dir, custom_logger=imit_logger.configure(log_dir, ["csv"]))


def train_gail(demos: list[Any], scaler: ObsScaler, action_acc_ft_s2: tuple[float, ...], *,
               seed: int, config: GailConfig, env_seed: int, log_dir: Path,
               scenario: str = "synthetic") -> tuple[Any, float]:
    """:func:`make_gail`'s trainer trained ``config.steps`` environment steps; returns
    ``(generator policy, wall seconds)`` (SUMO's simulation included)."""
    t0 = time.perf_counter()
    gail = make_gail(demos, scaler, action_acc_ft_s2, seed=seed, config=config, env_seed=env_seed,
                     log_dir=log_dir, scenario=scenario)
    gail.train(config.steps)
    gail.venv_train.close()
    return gail.gen_algo.policy, time.perf_counter() - t0


# -- the comparison ----------------------------------------------------------------------------
def demo_data(args) -> tuple[Path, dict[str, float]]:
    """The demo folder (run now, or ``--demo``) and the training wall times of its models (s)."""
    from analysis.demo.config import DemoConfig
    from analysis.demo.pipeline import run_demo

    if args.demo:
        folder = Path(args.demo)
    else:
        folder = Path(args.out) / "demo"
        cfg = DemoConfig(train_seeds=args.train_seeds, heldout_runs=args.heldout_runs, eval_episodes=1,
                         eval_duration_s=args.eval_duration, workers=args.workers)
        run_demo(folder, cfg, quiet=True, progress=False)
    times = json.loads((folder / "timings.json").read_text(encoding="utf-8")).get("fit_wall_time_s", {})
    return folder, {k: float(v) for k, v in times.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=5, help="evaluation seeds --seed .. --seed+N-1 (default 5)")
    ap.add_argument("--seed", type=int, default=1, help="first evaluation seed (default 1)")
    ap.add_argument("--eval-duration", type=float, default=180.0, help="simulated seconds per episode (default 180)")
    ap.add_argument("--train-seeds", type=lambda s: tuple(int(x) for x in s.split(",")), default=(101, 102, 103))
    ap.add_argument("--heldout-runs", type=int, default=10)
    ap.add_argument("--demo", default=None, help="reuse this demo folder (its data/ and models/) instead of running it")
    ap.add_argument("--train-seed", type=int, default=0, help="seed of torch, BC's batches and PPO (default 0)")
    ap.add_argument("--bc-epochs", type=int, default=20)
    gd = GailConfig()
    ap.add_argument("--gail-steps", type=int, default=gd.steps,
                    help=f"GAIL's generator (PPO) environment steps; 0: no GAIL (default {gd.steps})")
    ap.add_argument("--gail-n-steps", type=int, default=gd.n_steps,
                    help=f"PPO's rollout per GAIL round (default {gd.n_steps})")
    ap.add_argument("--gail-epochs", type=int, default=gd.n_epochs, help=f"PPO's epochs per rollout (default {gd.n_epochs})")
    ap.add_argument("--gail-lr", type=float, default=gd.learning_rate,
                    help=f"PPO's learning rate (default {gd.learning_rate:g})")
    ap.add_argument("--gail-disc-updates", type=int, default=gd.disc_updates,
                    help=f"discriminator updates per GAIL round (default {gd.disc_updates})")
    ap.add_argument("--gail-env-seed", type=int, default=3001,
                    help="SUMO seed of the environment's first run while GAIL trains (default 3001; later runs "
                         "draw theirs from it)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="runs/imitation-bench")
    args = ap.parse_args(argv)
    if args.gail_steps < 0:
        ap.error(f"--gail-steps must be 0 (no GAIL) or positive, got {args.gail_steps}")
    if args.gail_steps:
        try:
            args.gail = GailConfig(steps=args.gail_steps, n_steps=args.gail_n_steps, n_epochs=args.gail_epochs,
                                   learning_rate=args.gail_lr, disc_updates=args.gail_disc_updates)
        except ValueError as e:
            ap.error(str(e))
    print("command: python -m studies.imitation_bench " + shlex.join(sys.argv[1:] if argv is None else argv))
    return run(args)


def run(args) -> int:
    from analysis.evaluation.evaluate import evaluate
    from analysis.experiments.dagger import DaggerConfig
    from irl.domains.merge.car_following import car_following_decisions
    from irl.domains.merge.cf_logit import CarFollowingLogit
    from irl.domains.merge.mdp import read_encounters
    from sim.drivers.baselines import training_action_acc
    from sim.drivers.callables import CallablePolicy
    from sim.drivers.formats import driver_policy
    from sim.merges.transitions import from_encounters

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    folder, fit_s = demo_data(args)
    train_path, held_path = folder / "data" / "train_encounters.parquet", folder / "data" / "heldout_encounters.parquet"
    models = folder / "models"
    print(f"demonstrations: {folder} ({time.perf_counter() - t0:.0f} s)")
    step = DEFAULT_DECISION_STEP_S
    train_t = from_encounters(read_encounters(train_path), decision_step_s=step, where=str(train_path))
    held_t = from_encounters(read_encounters(held_path), decision_step_s=step, where=str(held_path))
    print(f"training decisions {train_t.n} ({train_t.n_episodes} encounters), held-out decisions {held_t.n} "
          f"({held_t.n_episodes} encounters), at {step} s")

    # cf-logit's fit alone (the demo times it with its DAgger rounds)
    t = time.perf_counter()
    CarFollowingLogit.fit(car_following_decisions(read_encounters(train_path), decision_step_s=step),
                          l2=DaggerConfig().l2)
    fit_s["cf-logit"] = time.perf_counter() - t

    scaler = ObsScaler.fit(train_t.obs)
    demos = to_imitation_trajectories(train_t)
    bc_policy, fit_s["imit-bc"] = train_bc(demos, scaler, seed=args.train_seed, epochs=args.bc_epochs,
                                           log_dir=out / "bc-log")
    fit_s["imit-bc-sampled"] = fit_s["imit-bc"]
    # the most likely action: the SB3 policy itself (CallablePolicy calls its predict(obs, deterministic=True))
    drivers: dict[str, Any] = {"imit-bc": bc_policy, "imit-bc-sampled": TorchActor(bc_policy, seed=args.train_seed)}
    print(f"imitation BC: {args.bc_epochs} epochs in {fit_s['imit-bc']:.1f} s")
    acc = training_action_acc(train_path)
    if args.gail_steps:
        gcfg = args.gail
        gail_policy, fit_s["imit-gail"] = train_gail(demos, scaler, acc, seed=args.train_seed, config=gcfg,
                                                     env_seed=args.gail_env_seed, log_dir=out / "gail-log")
        fit_s["imit-gail-sampled"] = fit_s["imit-gail"]
        drivers["imit-gail"] = gail_policy
        drivers["imit-gail-sampled"] = TorchActor(gail_policy, seed=args.train_seed)
        print(f"imitation GAIL: {gcfg} in {fit_s['imit-gail']:.0f} s")
        log = gail_log_summary(out / "gail-log" / "progress.csv")
        print("  GAIL's log, first round -> last: "
              + ", ".join(f"{k} {a:.3g} -> {b:.3g}" for k, (a, b) in log.items() if k != "steps"))
    for name, a in drivers.items():
        if isinstance(a, TorchActor):
            print(f"  {name}: mean entropy on the held-out decisions {mean_entropy(a, held_t.policy_obs()):.3f} nats "
                  f"(uniform {math.log(N_ACTIONS):.3f})")
    ll = {name: heldout_loglik(a, held_t) for name, a in drivers.items() if isinstance(a, TorchActor)}

    imit = [CallablePolicy(a, name=name, decision_step_s=step, action_acc_ft_s2=acc) for name, a in drivers.items()]
    ours = [driver_policy(models / f"{k}.json", name=k) for k in ("planner", "cf-logit")]
    rep = evaluate([models / "qavg.json"], "synthetic", args.episodes, args.seed, out / "evaluation",
                   duration_s=args.eval_duration, demos=held_path, train_demos=train_path, baselines=BASELINES,
                   policies=[*ours, *imit], workers=args.workers, rrd=False, progress=False)
    print(f"\nsynthetic, seeds {args.seed}-{args.seed + args.episodes - 1}, {args.eval_duration:.0f} s each; "
          f"decision step {step} s")
    print("| policy | training (s) | As | A collisions [95 % CI] | held-out LL/step | W1 TTC (s) | W1 speed (ft/s) "
          "| W1 acc (ft/s^2) | W1 d_AC (ft) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, a in rep.aggregates.items():
        lps = ll[name][1] if name in ll else a.heldout_loglik_per_step
        print(f"| {name} | {_f(fit_s.get(name), 1)} | {a.n_controls} | {a.a_collisions} "
              f"[{_f(a.a_collision_ci95[0])}, {_f(a.a_collision_ci95[1])}] | {_f(lps)} | {_f(a.w1_ttc_s, 2)} "
              f"| {_f(a.w1_speed_A_ft_s, 2)} | {_f(a.w1_acc_A_ft_s2, 2)} | {_f(a.w1_d_AC_ft, 1)} |")
    print(f"\ntotal {time.perf_counter() - t0:.0f} s; report {rep.report_md}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
