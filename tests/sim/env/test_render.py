"""``render_mode="rgb_array"``: Gymnasium's render checker, a frame with the road and A, B, C in
their colours where SUMO has them; without a render mode nothing is drawn."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from gymnasium.utils.passive_env_checker import env_render_passive_checker  # noqa: E402

from sim.env import MergeEnv  # noqa: E402
from sim.env.render import COLOURS  # noqa: E402

pytestmark = pytest.mark.sumo


def has(img, colour):
    return bool(np.any(np.all(img == np.array(colour, dtype=np.uint8), axis=-1)))


def test_rgb_array_frames_show_the_road_and_a_b_c():
    env = MergeEnv(run_s=240.0, render_mode="rgb_array")
    try:
        assert env.render() is None  # nothing to show before reset
        env.reset(seed=2)
        env_render_passive_checker(env)
        first = env.render()
        for _ in range(5):
            env.step(2)
        later = env.render()
    finally:
        env.close()
    assert first.shape == (160, 960, 3) and first.dtype == np.uint8
    for colour in ("asphalt", "marking", "A", "B", "other"):
        assert has(first, COLOURS[colour]), colour
    assert not np.array_equal(first, later)  # the cars moved


def test_without_a_render_mode_nothing_is_drawn():
    env = MergeEnv(run_s=240.0)
    try:
        env.reset(seed=2)
        env.step(2)
        assert env.render() is None and env._renderer is None
    finally:
        env.close()
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        MergeEnv(render_mode="human")
