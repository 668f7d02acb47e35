"""GAIL's training on the merge, diagnosed: does the generator leave the uniform policy, and why not.

For each GAIL setting given (``--config`` JSON, the fields of
:class:`studies.support.gail_config.GailConfig`), on the demo's synthetic demonstrations
(``--demo``, a folder :func:`analysis.demo.pipeline.run_demo` left), it trains
:func:`studies.imitation_bench.make_gail`'s trainer as the comparison does (``--train-seed``,
``--gail-env-seed``) and prints:

* PPO's policy entropy (nats; uniform: log 5 = 1.609), approximate KL and clip fraction, the
  discriminator's loss (chance: log 2 = 0.693) and accuracy, and the mean episode length, at
  the first round, every ``--every``-th and the last (GAIL's CSV log);
* the generator's mean entropy and log-likelihood per decision on the held-out decisions, its
  mean action probabilities beside the held-out demonstrations' action frequencies;
* the discriminator's reward (``-log(1 - D)``, imitation's GAIL reward) of every action at the
  held-out observations: its mean, the spread across actions at one observation (a flat
  reward: near 0) and across observations, and how often the demonstrated action has the
  highest reward.

No closed-loop evaluation (:mod:`studies.imitation_bench` does that). Needs the
``imitation-bench`` extra (docs/imitation.md). Run::

    python -m studies.gail_diagnosis --demo runs/demo --config '{"steps": 4096}' \\
        --config '{"steps": 32768}'
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np

from irl.domains.merge.actions import N_ACTIONS
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S
from studies.support.gail_config import GailConfig, parse_gail_config


def _row(r: dict[str, str], key: str) -> float:
    v = r.get(key) or ""
    return float(v) if v.strip() else math.nan


def diagnose(demo: Path, cfg: GailConfig, *, train_seed: int, env_seed: int, out: Path, every: int) -> None:
    """Train one GAIL setting and print its diagnosis (module docstring)."""
    from irl.domains.merge.mdp import read_encounters
    from sim.drivers.baselines import training_action_acc
    from sim.merges.transitions import from_encounters, to_imitation_trajectories
    from studies.imitation_bench import TorchActor, heldout_loglik, make_gail, mean_entropy
    from studies.support.obs_scaler import ObsScaler

    tp, hp = demo / "data" / "train_encounters.parquet", demo / "data" / "heldout_encounters.parquet"
    step = DEFAULT_DECISION_STEP_S
    train = from_encounters(read_encounters(tp), decision_step_s=step, where=str(tp))
    held = from_encounters(read_encounters(hp), decision_step_s=step, where=str(hp))
    t0 = time.perf_counter()
    gail = make_gail(to_imitation_trajectories(train), ObsScaler.fit(train.obs), training_action_acc(tp),
                     seed=train_seed, config=cfg, env_seed=env_seed, log_dir=out)
    gail.train(cfg.steps)
    gail.venv_train.close()
    wall = time.perf_counter() - t0
    print(f"== {cfg}: {wall:.0f} s; demonstrations' episode {train.n / train.n_episodes:.1f} decisions")
    with open(out / "progress.csv", encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for i, r in enumerate(rows):
        if i == 0 or (i + 1) % every == 0 or i == len(rows) - 1:
            print(f"  steps {_row(r, 'mean/gen/time/total_timesteps'):6.0f}  "
                  f"entropy {-_row(r, 'mean/gen/train/entropy_loss'):.3f}  "
                  f"KL {_row(r, 'mean/gen/train/approx_kl'):.1e}  clip {_row(r, 'mean/gen/train/clip_fraction'):.3f}  "
                  f"disc loss {_row(r, 'mean/disc/disc_loss'):.3f}  disc acc {_row(r, 'mean/disc/disc_acc'):.2f}  "
                  f"episode {_row(r, 'mean/gen/rollout/ep_len_mean'):.1f}")
    actor = TorchActor(gail.gen_algo.policy, seed=train_seed)
    obs = held.policy_obs()
    p = actor.probs(obs)
    print(f"  held-out: entropy {mean_entropy(actor, obs):.3f}, LL/step {heldout_loglik(actor, held)[1]:.3f}; "
          f"mean probabilities {np.round(p.mean(axis=0), 3).tolist()}, demonstrated "
          f"{np.round(np.bincount(held.acts, minlength=N_ACTIONS) / held.n, 3).tolist()}")
    rew = np.column_stack([gail.reward_test.predict(obs, np.full(held.n, a), obs, np.zeros(held.n, dtype=bool))
                           for a in range(N_ACTIONS)])
    print(f"  reward -log(1-D): mean {rew.mean():.3f}, sd across actions {rew.std(axis=1).mean():.3f}, "
          f"sd across observations {rew.mean(axis=1).std():.3f}, demonstrated action highest "
          f"{np.mean(rew.argmax(axis=1) == held.acts):.3f}; per action {[round(float(x), 3) for x in rew.mean(axis=0)]}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", required=True, help="a demo folder (its data/)")
    ap.add_argument("--config", action="append", required=True,
                    help="GailConfig fields as JSON, e.g. '{\"steps\": 32768}'; repeat for several")
    ap.add_argument("--train-seed", type=int, default=0)
    ap.add_argument("--gail-env-seed", type=int, default=3001)
    ap.add_argument("--every", type=int, default=8, help="print every N-th round of the log (default 8)")
    ap.add_argument("--out", default="runs/gail-diagnosis")
    args = ap.parse_args(argv)
    demo = Path(args.demo)
    if not (demo / "data" / "train_encounters.parquet").is_file():
        ap.error(f"--demo {demo}: no data/train_encounters.parquet")
    try:
        configs = [parse_gail_config(c) for c in args.config]
    except ValueError as e:
        ap.error(str(e))
    for i, c in enumerate(configs):
        diagnose(demo, c, train_seed=args.train_seed, env_seed=args.gail_env_seed, out=Path(args.out) / str(i),
                 every=args.every)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
