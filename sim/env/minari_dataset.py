"""Transitions as a Minari dataset (``merge-irl export-transitions --format minari``; Minari is in
the ``rl`` extra and imported inside the functions).

:func:`write_minari` writes :class:`sim.merges.transitions.Transitions` as a dataset that
``minari.load_dataset(dataset_id)`` reads back, one Minari episode per episode of the transitions:

* observation space: :class:`sim.env.merge_env.MergeEnv`'s ``Box(OBS_LOW, OBS_HIGH, (7,),
  float64)`` (ft, ft/s; its default ``units="ft"``); ``observations`` ``[n_e + 1, 7]``, the
  episode's policy observations (:meth:`~sim.merges.transitions.Transitions.policy_obs`) and the
  last ``next_obs``, as the environment gives them;
* action space: ``Discrete(5)``, the merge actions 0..4 (the environment's ``action_type="discrete"``);
  ``actions`` ``[n_e]``;
* ``rewards`` ``[n_e]``: 0 (demonstrations carry no reward; the environment's ``reward="zero"``);
  ``terminations`` ``[n_e]``: True at the last decision (an encounter's or a control's end),
  ``truncations`` all False;
* metadata: Minari's (``dataset_id``, ``algorithm_name`` ``"demonstrations"``, ``description``,
  ``eval_env_spec``: ``MergeIRL/OnRampMerge-v0`` with its defaults) and ``merge_irl``: the
  run's provenance (:func:`merge_irl.provenance.provenance`, given by the caller), the
  observation columns and units, the action names, the decision step (s) and the reward.

Datasets go under ``root`` (default: Minari's, ``MINARI_DATASETS_PATH`` or
``~/.minari/datasets``), in ``root/<dataset_id>/data``. The dataset is written in a hidden
folder of ``root`` first and moved into place when complete, so a failed export leaves nothing
and an overwritten dataset is replaced whole. Minari's ``arrow`` format (pyarrow, a dependency of
this project; its default ``hdf5`` needs h5py).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from irl.domains.merge.actions import ACTION_NAMES, N_ACTIONS
from sim.drivers.observe import CONTINUOUS_UNITS
from sim.errors import SimError

#: Minari's storage format of the exported datasets.
DATA_FORMAT = "arrow"
#: The metadata key of this project's entries.
METADATA_KEY = "merge_irl"
_NAMESPACE_FILE = "namespace_metadata.json"


class MinariExportError(SimError, ValueError):
    """A dataset that cannot be written as asked (the message names the id or folder)."""


class Transitions(Protocol):
    """What :func:`write_minari` reads of :class:`sim.merges.transitions.Transitions` (``sim.env``
    sits below ``sim.merges`` and does not import it)."""

    @property
    def acts(self) -> np.ndarray: ...

    @property
    def obs_names(self) -> tuple[str, ...]: ...

    @property
    def decision_step_s(self) -> float: ...

    @property
    def n(self) -> int: ...

    @property
    def n_episodes(self) -> int: ...

    def episodes(self) -> list[np.ndarray]: ...

    def policy_obs(self) -> np.ndarray: ...

    def policy_next_obs(self) -> np.ndarray: ...


def default_root() -> Path:
    """Minari's datasets folder: ``MINARI_DATASETS_PATH`` when set, else ``~/.minari/datasets``."""
    env = os.environ.get("MINARI_DATASETS_PATH")
    return Path(env) if env else Path.home() / ".minari" / "datasets"


def check_dataset_id(dataset_id: str, root: str | os.PathLike | None = None, *, overwrite: bool = False) -> Path:
    """The folder ``dataset_id`` would be written to under ``root`` (default :func:`default_root`).

    Raises:
        MinariExportError: an id not of Minari's form ``(namespace/)name-v(version)``, or a dataset
            of that id already in ``root`` and ``overwrite`` False.
    """
    from minari.dataset.minari_dataset import parse_dataset_id

    try:
        parse_dataset_id(dataset_id)
    except (ValueError, TypeError):  # Minari 0.5.4 raises TypeError for an id without its -v(version)
        raise MinariExportError(f"dataset id {dataset_id!r}: not a Minari dataset id, (namespace/)name-v(version), "
                                "e.g. merge-irl/demos-v0") from None
    target = Path(root if root is not None else default_root()) / dataset_id
    if target.exists() and not overwrite:
        raise MinariExportError(f"{target}: a Minari dataset {dataset_id!r} exists already (replace it with "
                                "--overwrite, overwrite=True in Python, or choose another id)")
    return target


def episode_buffers(t: Transitions) -> list[Any]:
    """One ``minari.data_collector.EpisodeBuffer`` per episode of ``t`` (module docstring: arrays)."""
    from minari.data_collector import EpisodeBuffer

    pobs, pnext = t.policy_obs(), t.policy_next_obs()
    out = []
    for i, rows in enumerate(t.episodes()):
        n = rows.size
        term = np.zeros(n, dtype=bool)
        term[-1] = True
        out.append(EpisodeBuffer(id=i, observations=np.concatenate([pobs[rows], pnext[rows[-1:]]]),
                                 actions=t.acts[rows].copy(), rewards=list(np.zeros(n)),
                                 terminations=list(term), truncations=list(np.zeros(n, dtype=bool))))
    return out


def project_metadata(t: Transitions, provenance: Mapping[str, Any] | None) -> dict[str, Any]:
    """The ``merge_irl`` metadata entry of ``t`` (JSON-ready)."""
    return {"provenance": dict(provenance or {}), "obs_names": list(t.obs_names),
            "obs_units": list(CONTINUOUS_UNITS), "action_names": list(ACTION_NAMES),
            "decision_step_s": t.decision_step_s, "reward": "zero: demonstrations carry no reward",
            "terminations": "True at each episode's last decision (its encounter's or control's end)"}


def write_minari(t: Transitions, dataset_id: str, *, root: str | os.PathLike | None = None, overwrite: bool = False,
                 provenance: Mapping[str, Any] | None = None, description: str | None = None) -> Any:
    """Write ``t`` as the Minari dataset ``dataset_id`` under ``root`` (module docstring) and return
    it as ``minari.MinariDataset``, read back from its folder.

    Args:
        t: the transitions (at least one).
        dataset_id: Minari's ``(namespace/)name-v(version)``.
        root: the datasets folder (None: :func:`default_root`).
        overwrite: replace a dataset of the same id.
        provenance: the run's provenance record, kept in the metadata.
        description: Minari's ``description`` (None: a line naming the counts).

    Raises:
        MinariExportError: no transitions, a bad id or an existing one (:func:`check_dataset_id`).
        OSError: the folder cannot be written.
    """
    import gymnasium as gym
    import minari

    import sim.env  # noqa: F401  (registers the environment id of eval_env_spec)
    from sim.env import ENV_ID
    from sim.env.merge_env import OBS_HIGH, OBS_LOW

    if not t.n:
        raise MinariExportError(f"{dataset_id}: no transitions to write")
    # absolute: Minari's arrow writer doubles a relative folder into the path it writes to
    root_dir = (Path(root) if root is not None else default_root()).absolute()
    target = check_dataset_id(dataset_id, root_dir, overwrite=overwrite)
    root_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".merge-irl-export-", dir=root_dir))
    try:
        with _datasets_path(tmp), warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*is set to None.*", category=UserWarning)
            warnings.filterwarnings("ignore", message=".*no environment spec.*", category=UserWarning)
            ds = minari.create_dataset_from_buffers(
                dataset_id, episode_buffers(t), observation_space=gym.spaces.Box(OBS_LOW, OBS_HIGH, dtype=np.float64),
                action_space=gym.spaces.Discrete(N_ACTIONS), eval_env=gym.spec(ENV_ID),
                algorithm_name="demonstrations", data_format=DATA_FORMAT,
                description=description or (f"{t.n} decisions of car A in {t.n_episodes} merges, every "
                                            f"{t.decision_step_s:g} s (merge-irl export-transitions)"))
            ds.storage.update_metadata({METADATA_KEY: project_metadata(t, provenance)})
        _move_into_place(tmp, root_dir, dataset_id)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return minari.MinariDataset(target / "data")


class _datasets_path:
    """``MINARI_DATASETS_PATH`` set to ``path`` inside the block (Minari's API takes no folder)."""

    def __init__(self, path: Path):
        self.path, self.old = str(path), os.environ.get("MINARI_DATASETS_PATH")

    def __enter__(self) -> None:
        os.environ["MINARI_DATASETS_PATH"] = self.path

    def __exit__(self, *exc: Any) -> None:
        if self.old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = self.old


def _move_into_place(tmp: Path, root: Path, dataset_id: str) -> None:
    """Move ``tmp/dataset_id`` to ``root/dataset_id`` (an old one there removed only after), with
    the namespace files Minari wrote for the id's namespaces where ``root`` has none."""
    parts = Path(dataset_id).parts
    for i in range(1, len(parts)):  # the namespaces: a, a/b, ...
        ns = Path(*parts[:i])
        (root / ns).mkdir(parents=True, exist_ok=True)
        if (tmp / ns / _NAMESPACE_FILE).is_file() and not (root / ns / _NAMESPACE_FILE).exists():
            shutil.copyfile(tmp / ns / _NAMESPACE_FILE, root / ns / _NAMESPACE_FILE)
    target, old = root / dataset_id, tmp / ".replaced"
    if target.exists():
        target.rename(old)
    (tmp / dataset_id).rename(target)
