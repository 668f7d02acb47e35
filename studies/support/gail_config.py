"""GAIL's settings and the reader of its training log, without torch or ``imitation``.

:class:`GailConfig` is the budget and the learners' settings of the GAIL trainer that
``studies/imitation_bench.py`` builds (the ``imitation-bench`` extra: torch, ``imitation``,
Stable-Baselines3); :func:`parse_gail_config` reads one from JSON (``studies/gail_diagnosis.py``'s
``--config``); :func:`gail_log_summary` reads the first and the last round of the trainer's CSV
log. All of it runs in the default install.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class GailConfig:
    """GAIL's budget and its learners' settings (``studies/imitation_bench.py``'s ``make_gail``
    and ``train_gail``).

    Attributes:
        steps: the generator's (PPO's) environment steps in all.
        n_steps: PPO's rollout per round (environment steps; GAIL's round: one rollout, then
            ``disc_updates`` discriminator updates).
        batch_size, n_epochs, learning_rate, ent_coef, gamma: PPO's minibatch, epochs per rollout,
            Adam step size, entropy bonus and discount.
        disc_updates: discriminator updates per round (each on ``demo_batch_size`` demonstration
            and as many generated transitions).
        disc_lr: the discriminator's Adam step size.
        demo_batch_size: demonstration transitions per discriminator update.

    Raises:
        ValueError: a count below 1, ``steps`` below ``n_steps`` (not one round), a learning rate
            not above 0, ``gamma`` outside (0, 1] or a negative ``ent_coef``.
    """

    steps: int = 32768
    n_steps: int = 512
    batch_size: int = 64
    n_epochs: int = 4
    learning_rate: float = 3e-4
    ent_coef: float = 0.0
    gamma: float = 0.99
    disc_updates: int = 4
    disc_lr: float = 1e-3
    demo_batch_size: int = 256

    def __post_init__(self) -> None:
        counts = ("steps", "n_steps", "batch_size", "n_epochs", "disc_updates", "demo_batch_size")
        for name in counts:
            if getattr(self, name) < 1:
                raise ValueError(f"GAIL's {name} must be at least 1, got {getattr(self, name)}")
        if self.steps < self.n_steps:
            raise ValueError(f"GAIL's steps ({self.steps}) must be at least one round of n_steps ({self.n_steps})")
        if not (self.learning_rate > 0 and self.disc_lr > 0 and 0 < self.gamma <= 1 and self.ent_coef >= 0):
            raise ValueError(f"GAIL's learning rates must be > 0, gamma in (0, 1] and ent_coef >= 0, got {self}")


def parse_gail_config(text: str) -> GailConfig:
    """A :class:`GailConfig` from a JSON object of its fields (the others keep their defaults),
    e.g. ``'{"steps": 4096, "disc_updates": 16}'``.

    Raises:
        ValueError: not JSON, not a JSON object, an unknown field, or a value the config refuses.
    """
    try:
        fields = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"GAIL config {text!r}: not JSON ({e})") from None
    if not isinstance(fields, dict):
        raise ValueError(f"GAIL config {text!r}: a JSON object of GailConfig's fields expected")
    try:
        return GailConfig(**fields)
    except TypeError as e:
        raise ValueError(f"GAIL config {text!r}: {e}") from None


#: The columns of GAIL's CSV log (``gail-log/progress.csv``) :func:`gail_log_summary` reads, by short name.
GAIL_LOG_COLUMNS = {"steps": "mean/gen/time/total_timesteps", "entropy": "mean/gen/train/entropy_loss",
                    "approx_kl": "mean/gen/train/approx_kl", "disc_loss": "mean/disc/disc_loss",
                    "disc_acc": "mean/disc/disc_acc", "ep_len": "mean/gen/rollout/ep_len_mean"}


def gail_log_summary(progress_csv: Path) -> dict[str, tuple[float, float]]:
    """``{name: (first round, last round)}`` of GAIL's CSV log (:data:`GAIL_LOG_COLUMNS`; the
    entropy as PPO's policy entropy, nats, the negated ``entropy_loss``); NaN where a round
    lacks the column.

    Raises:
        FileNotFoundError: no log at ``progress_csv``.
        ValueError: the log has no rounds.
    """
    with open(progress_csv, encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise ValueError(f"{progress_csv}: GAIL's log has no rounds")

    def val(row: dict[str, str], col: str) -> float:
        v = row.get(col) or ""
        return float(v) if v.strip() else math.nan

    out = {k: (val(rows[0], c), val(rows[-1], c)) for k, c in GAIL_LOG_COLUMNS.items()}
    out["entropy"] = (-out["entropy"][0], -out["entropy"][1])
    return out
