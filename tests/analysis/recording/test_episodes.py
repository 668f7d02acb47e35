"""The environment's episodes written to rerun by ``RecordRerun``, read back with
``rerun.chunk.RrdReader``: one file per episode, the closed loop's entities, one ``world/vehicles``
row per frame of the episode, A's decisions one per step."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from analysis.recording.episodes import RecordRerun  # noqa: E402
from analysis.recording.read import read_entities, recording_info  # noqa: E402
from sim.env import MergeEnv  # noqa: E402

pytestmark = pytest.mark.sumo


def _steps(batches, column="step"):
    return np.concatenate([b.column(column).to_numpy() for b in batches])


def test_each_episode_is_one_rrd_with_the_closed_loops_entities(tmp_path):
    env = RecordRerun(MergeEnv(run_s=240.0), tmp_path / "rrd", name_prefix="ep")
    episodes = []
    try:
        for k in range(2):
            _, info = env.reset(seed=2) if k == 0 else env.reset()
            a_id, times, n, done = info["a_id"], [info["time_s"]], 0, False
            while not done:
                _, _, terminated, truncated, info = env.step(k * 2)  # High Brake, then Zero
                times.append(info["time_s"])
                n, done = n + 1, terminated or truncated
            episodes.append((a_id, n, times))
    finally:
        env.close()
    assert [p.name for p in env.paths] == ["ep-0.rrd", "ep-1.rrd"]
    assert not list((tmp_path / "rrd").glob("*.partial"))
    for k, (path, (a_id, n, times)) in enumerate(zip(env.paths, episodes)):
        ents = read_entities(path)
        for entity in ("/world", "/world/lanes", "/world/road", "/world/vehicles", "/follow",
                       f"/policy/A_{a_id}/action", f"/policy/A_{a_id}/probs", f"/metrics/A_{a_id}/speed"):
            assert entity in ents, (k, entity)
        assert not [e for e in ents if e.startswith("/policy/A_") and f"/A_{a_id}/" not in e]  # its A only
        steps = _steps(ents["/world/vehicles"])
        # every frame from the take-over to the release, once: 3 frames per 0.3 s decision
        assert np.array_equal(steps, np.arange(steps[0], steps[0] + steps.size))
        assert steps.size == pytest.approx(round((times[-1] - times[0]) / 0.1) + 1, abs=1)
        actions = np.concatenate([b.column("Scalars:scalars").to_numpy(zero_copy_only=False)
                                  for b in ents[f"/policy/A_{a_id}/action"]])
        assert actions.size == n  # one decision per step
        assert set(np.concatenate(actions).astype(int)) == {0 if k == 0 else 2}
        info = recording_info(path)
        assert "agent" in (info["name"] or "") and f"episode {k}" in (info["name"] or "")


def test_a_refused_action_goes_on_and_a_failed_step_leaves_the_partial_file(tmp_path):
    env = RecordRerun(MergeEnv(run_s=240.0), tmp_path, episode_trigger=lambda k: k == 0)
    try:
        env.reset(seed=2)
        env.step(2)
        with pytest.raises(ValueError, match="action must be"):
            env.step(7)
        env.step(2)

        def broken():
            raise RuntimeError("SUMO went away")

        env.unwrapped._session.step = broken
        with pytest.raises(RuntimeError, match="SUMO went away"):
            env.step(2)
    finally:
        del env.unwrapped._session.step
        env.close()
    assert env.paths == [] and not (tmp_path / "episode-0.rrd").exists() and len(list(tmp_path.iterdir())) == 1
    assert [p.name for p in tmp_path.iterdir()][0].endswith(".partial")  # the temporary file, kept
    assert env.unwrapped.frame_listeners == []  # close takes the wrapper's listener away
