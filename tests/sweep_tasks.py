"""Top-level task functions used by the sweep tests (importable by worker processes)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class DrawConfig:
    n: int
    sleep_s: float = 0.0
    marker_dir: str = ""


def draw(config: DrawConfig, seed: int) -> dict:
    """Draw ``n`` normals with the task's seed; optionally sleep, optionally leave a marker."""
    if config.sleep_s:
        time.sleep(config.sleep_s)
    rng = np.random.default_rng(seed)
    if config.marker_dir:
        Path(config.marker_dir, f"{seed}").touch()
    return {"values": rng.normal(size=config.n).tolist()}


@dataclass(frozen=True)
class FlakyConfig:
    mode: str  # "raise" | "crash" | "raise-once" | "policy-error"
    marker_dir: str = ""


def flaky(config: FlakyConfig, seed: int) -> dict:
    """Fails on purpose: raises, kills its own process, or raises on the first attempt only."""
    if config.mode == "raise":
        raise RuntimeError("task failed on purpose")
    if config.mode == "crash":
        os._exit(13)
    if config.mode == "policy-error":  # deterministic: the same inputs fail the same way
        from sim.drivers.policy import PolicyError

        raise PolicyError("policy 'x': returned action 7")
    if config.mode == "raise-once":
        marker = Path(config.marker_dir, "attempted")
        if not marker.exists():
            marker.touch()
            raise RuntimeError("first attempt fails")
        return {"attempt": 2}
    raise ValueError(config.mode)


@dataclass(frozen=True)
class SleepConfig:
    sleep_s: float
    marker_dir: str


def mark_then_sleep(config: SleepConfig, seed: int) -> dict:
    """Leave ``started-<pid>`` in ``marker_dir`` (so a test can kill this very process), then sleep."""
    Path(config.marker_dir, f"started-{os.getpid()}").touch()
    time.sleep(config.sleep_s)
    return {"pid": os.getpid()}
