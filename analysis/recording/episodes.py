"""The Gymnasium environment's episodes written to rerun ``.rrd`` files, one file per episode.

:class:`RecordRerun` wraps a :class:`sim.env.MergeEnv` (or ``gym.make("MergeIRL/OnRampMerge-v0")``)
and writes each episode it records with the closed loop's own logger
(:class:`analysis.recording.log.RerunLogger`): the same entities (``world/road``, ``world/lanes``,
``world/landmarks``, ``world/vehicles``, ``follow``, ``policy/A_<id>/...``,
``metrics/A_<id>/...``), timelines (``step``, ``sim_time``) and blueprint, fed every frame of the
episode from the take-over to the release as the closed loop's step hook is (the environment's
``frame_listeners``). The agent shows as the controlled car A; its actions as
``policy/A_<id>/action`` (``probs``: one-hot of the applied action's bin, the agent having no
distribution to log). A file is ``<folder>/<name_prefix>-<k>.rrd`` for the ``k``-th episode since
the wrapper was made (from 0), written under a temporary ``.partial`` name and renamed when the episode ends
(terminated, truncated, ``reset`` or ``close`` before its end); a ``step`` that fails (SUMO, Ctrl-C;
not an action refused with ``ValueError``, which changes nothing) leaves the temporary file,
never a complete-looking ``.rrd``. Headless: no viewer is started.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

from analysis.recording.log import RerunLogger

__all__ = ["RecordRerun"]


class _EpisodeController:
    """The run's controller as the logger of one episode sees it: its control only."""

    def __init__(self, controller: Any, control: Any):
        self._controller = controller
        self.controls = [control] if control is not None else []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._controller, name)


class RecordRerun(gym.Wrapper):
    """Writes the episodes of ``env`` to ``.rrd`` files (module docstring).

    Args:
        env: a :class:`sim.env.MergeEnv`, possibly wrapped (``gym.make``).
        folder: where the files go (made when missing).
        name_prefix: the files' name before ``-<k>.rrd``.
        episode_trigger: ``trigger(k) -> bool``, which episodes to record (None: every one).

    Attributes:
        paths: the files written so far, in order.

    Raises:
        TypeError: ``env`` is not a :class:`sim.env.MergeEnv` underneath.
    """

    def __init__(self, env: gym.Env, folder: str | os.PathLike, *, name_prefix: str = "episode",
                 episode_trigger: Callable[[int], bool] | None = None):
        super().__init__(env)
        if not hasattr(env.unwrapped, "frame_listeners"):
            raise TypeError(f"RecordRerun: env must be a sim.env.MergeEnv (wrapped or not), got {env.unwrapped!r}")
        self.folder = Path(folder)
        self.name_prefix = name_prefix
        self.episode_trigger = episode_trigger
        self.paths: list[Path] = []
        self._episode = -1
        self._recording = False
        self._logger: RerunLogger | None = None
        self._ctx: Any = None
        env.unwrapped.frame_listeners.append(self._on_frame)

    def reset(self, **kwargs: Any) -> Any:
        self._finish()
        out = self.env.reset(**kwargs)
        self._episode += 1
        self._recording = self.episode_trigger is None or bool(self.episode_trigger(self._episode))
        return out

    def step(self, action: Any) -> Any:
        try:
            obs, reward, terminated, truncated, info = self.env.step(action)
        except ValueError:  # an action refused: nothing was applied, the episode goes on
            raise
        except BaseException:
            self._abort()
            raise
        if terminated or truncated:
            self._finish()
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        self._finish()
        listeners = getattr(self.env.unwrapped, "frame_listeners", [])
        if self._on_frame in listeners:
            listeners.remove(self._on_frame)
        super().close()

    # -- internals ----------------------------------------------------------------------
    def _on_frame(self, ctx: Any, controller: Any, frame: Any) -> None:
        if not self._recording:
            return
        if self._logger is None:  # the episode's first frame: its take-over
            self.folder.mkdir(parents=True, exist_ok=True)
            path = self.folder / f"{self.name_prefix}-{self._episode}.rrd"
            active = [c for c in controller.controls if c.active]  # the agent's: one at a time
            self._logger = RerunLogger(path, controller=_EpisodeController(controller, active[-1] if active else None),
                                       episode=self._episode)
            self._ctx = ctx
            self._logger.on_start(ctx)
        self._logger.on_step(ctx, frame)

    def _finish(self) -> None:
        """The episode's file written and renamed (when one is open)."""
        if self._logger is not None:
            logger, self._logger = self._logger, None
            logger.on_end(self._ctx)
            self.paths.append(logger.path)
        self._recording = False

    def _abort(self) -> None:
        """A step failed: the file is left under its ``.partial`` name."""
        if self._logger is not None:
            logger, self._logger = self._logger, None
            logger.on_abort(self._ctx)
        self._recording = False
