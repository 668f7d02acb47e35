"""``gymnasium.wrappers.RecordVideo`` over the environment writes an mp4 of its ``rgb_array``
frames through moviepy (the ``[video]`` extra)."""

from __future__ import annotations

import pytest
from extras import require_extra

pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

import gymnasium as gym  # noqa: E402

import sim.env  # noqa: E402, F401  (registers MergeIRL/OnRampMerge-v0)

pytestmark = pytest.mark.sumo


def test_record_video_writes_an_mp4_of_an_episode(tmp_path):
    require_extra("moviepy", "video")
    env = gym.wrappers.RecordVideo(
        gym.make("MergeIRL/OnRampMerge-v0", run_s=240.0, render_mode="rgb_array", max_episode_steps=12),
        str(tmp_path / "videos"), episode_trigger=lambda i: True, name_prefix="merge", disable_logger=True)
    try:
        env.reset(seed=2)
        done, n = False, 0
        while not done:
            _, _, terminated, truncated, _ = env.step(2)
            done, n = terminated or truncated, n + 1
        assert len(env.recorded_frames) == n + 1  # the reset's frame and one per step
    finally:
        env.close()  # writes the episode's file
    (mp4,) = sorted((tmp_path / "videos").glob("*.mp4"))
    assert mp4.name == "merge-episode-0.mp4" and mp4.stat().st_size > 1000
    from moviepy import VideoFileClip

    with VideoFileClip(str(mp4)) as clip:
        assert tuple(clip.size) == (960, 160)
        assert clip.duration == pytest.approx((n + 1) / 10, abs=0.15)  # render_fps 10
