"""``render_mode="rgb_array"``: Gymnasium's render checker, a frame with the road and A, B, C in
their colours where SUMO has them, the legend, the letters A, B, C above their cars, the clock and
the scale bar where the renderer says they are; without a render mode nothing is drawn."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from gymnasium.utils.passive_env_checker import env_render_passive_checker  # noqa: E402

from merge_irl.units import FT_PER_M  # noqa: E402
from sim.env import MergeEnv  # noqa: E402
from sim.env.glyphs import text_mask  # noqa: E402
from sim.env.render import COLOURS, HEADER_H, LEGEND  # noqa: E402

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


def box(img, b):
    r0, r1, c0, c1 = b
    return img[r0:r1, c0:c1]


def test_frames_carry_legend_labels_clock_and_scale_bar():
    env = MergeEnv(run_s=240.0, render_mode="rgb_array")
    try:
        env.reset(seed=2)
        first = env.render()
        again = env.render()
        rnd = env.unwrapped._renderer
        labels = dict(rnd.label_boxes)
        frame, roles = env._frame, dict(env._ctl.role_rows)
        for _ in range(5):
            env.step(2)
        later = env.render()
    finally:
        env.close()
    np.testing.assert_array_equal(first, again)  # the same frame draws the same picture
    # the header strip: no road drawn into it
    assert not has(first[:HEADER_H], COLOURS["asphalt"]) and not has(first[:HEADER_H], COLOURS["grass"])
    legend = box(first, rnd.legend_box)
    for key, _ in LEGEND:  # a swatch of every colour, and text
        assert has(legend, COLOURS[key]), key
    assert has(legend, COLOURS["text"])
    # the clock: the frame's time written at the left; it changes when the time does
    clock = box(first, rnd.clock_box)
    written = np.all(clock == np.array(COLOURS["text"], dtype=np.uint8), axis=-1)
    mask = text_mask(f"t {frame.time_s:.1f} s")
    np.testing.assert_array_equal(written[2:2 + mask.shape[0], 4:4 + mask.shape[1]], mask)
    assert not np.array_equal(clock, box(later, rnd.clock_box))
    assert np.array_equal(box(first, rnd.legend_box), box(later, rnd.legend_box))  # the legend stays
    # the scale bar: a white line of the bar's length in metres at the road's scale
    bar_row = box(first, rnd.scale_box)[HEADER_H // 2]
    white = np.all(bar_row == np.array(COLOURS["text"], dtype=np.uint8), axis=-1).astype(int)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], white, [0]])))
    longest = int(np.max(edges[1::2] - edges[::2]))  # the bar, not the label's letters
    assert abs(longest - rnd.scale_m * FT_PER_M * rnd.sx) <= 1
    # a letter above (or below) each car of a role, next to that car
    assert set(labels) == set(roles.values()) and {"A", "B"} <= set(labels)
    x1, yc = rnd._px(frame.global_x, frame.global_y)
    for row, role in roles.items():
        r0, r1, c0, c1 = labels[role]
        letter = box(first, labels[role])
        assert np.array_equal(np.all(letter[1:-1, 1:-1] == np.array(COLOURS["text"], dtype=np.uint8), axis=-1),
                              text_mask(role)), role
        assert c0 - 8 <= x1[row] <= c1 + 8 + frame.length[row] * rnd.sx  # over the car, along the road
        assert min(abs(yc[row] - r0), abs(yc[row] - r1)) <= 12  # just above or below it
