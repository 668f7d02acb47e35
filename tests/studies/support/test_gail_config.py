"""analysis/experiments/gail_config.py: GAIL's settings, read from JSON, and its CSV log, without torch."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from studies.support.gail_config import GAIL_LOG_COLUMNS, GailConfig, gail_log_summary, parse_gail_config


def test_gail_log_summary_reads_first_and_last_round_and_negates_the_entropy_loss(tmp_path: Path) -> None:
    cols = list(GAIL_LOG_COLUMNS.values())
    rows = [{"mean/gen/time/total_timesteps": "512", "mean/gen/train/entropy_loss": "-1.609",
             "mean/gen/train/approx_kl": "0.0001", "mean/disc/disc_loss": "0.70", "mean/disc/disc_acc": "0.5",
             "mean/gen/rollout/ep_len_mean": ""},
            {"mean/gen/time/total_timesteps": "1024", "mean/gen/train/entropy_loss": "-1.2",
             "mean/gen/train/approx_kl": "0.01", "mean/disc/disc_loss": "0.55", "mean/disc/disc_acc": "0.7",
             "mean/gen/rollout/ep_len_mean": "24.5"}]
    log = tmp_path / "progress.csv"
    log.write_text(",".join(["other", *cols]) + "\n"
                   + "\n".join(",".join(["9", *(r[c] for c in cols)]) for r in rows) + "\n", encoding="utf-8")
    s = gail_log_summary(log)
    assert set(s) == set(GAIL_LOG_COLUMNS)
    assert s["steps"] == (512.0, 1024.0)
    assert s["entropy"] == (1.609, 1.2)
    assert s["disc_loss"] == (0.70, 0.55)
    assert math.isnan(s["ep_len"][0]) and s["ep_len"][1] == 24.5
    (tmp_path / "empty.csv").write_text(",".join(cols) + "\n", encoding="utf-8")
    with pytest.raises(ValueError, match="no rounds"):
        gail_log_summary(tmp_path / "empty.csv")


def test_gail_config_refuses_what_imitation_would_fail_on_late() -> None:
    assert GailConfig().steps == 32768 and GailConfig().steps % GailConfig().n_steps == 0
    for bad in ({"steps": 100}, {"n_steps": 0}, {"disc_updates": 0}, {"learning_rate": 0.0}, {"gamma": 1.5},
                {"ent_coef": -0.1}):
        with pytest.raises(ValueError, match="GAIL's"):
            GailConfig(**bad)
    assert parse_gail_config('{"steps": 1024, "disc_updates": 16}') == GailConfig(steps=1024, disc_updates=16)
    for bad_text in ("{steps: 1}", "[1]", '{"stepz": 1}', '{"steps": 0}'):
        with pytest.raises(ValueError):
            parse_gail_config(bad_text)
