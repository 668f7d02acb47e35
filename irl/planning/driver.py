"""The planning driver (:class:`PlanningDriver`), its JSON file (format ``merge-irl-planner/1``)
and :func:`learn_planning_driver`.

The driver chooses A's acceleration on the fine grid of its :class:`~irl.planning.model.PlannerConfig`
(the first action of a receding-horizon tree, :mod:`irl.planning.model`), by the softmax of its backed-up
values (:mod:`irl.planning.policy`); it is scored on the five paper actions, each the sum of its fine actions'
probabilities.

**Action history (the copycat).** A reward with a fitted jerk weight (``PlannerConfig(jerk=True)``)
has the best held-out likelihood (NGSIM I-80 pairs at 0.3 s: about -0.35 nats per decision) but
its weight (about -64) makes the closed-loop driver repeat its own last acceleration: replaying
held-out pairs from the recorded start (``prev_acc`` 0) its median spacing RMSE is about 130 m
(the leader pulls away), the causal confusion of imitation with action history (de Haan et al.
2019, "Causal confusion in imitation learning", NeurIPS; Wen et al. 2020, NeurIPS). Neither a
higher desired speed (``v0_ft_s``, ``free_road``) nor an actuation lag fitted by likelihood
(``lag``) fixes it. The default reward therefore has **no** action history (``jerk=False``: held-out
LL about -1.07, median replay RMSE about 5.6 m, no collisions); ``jerk_weight`` fixes a small
jerk weight instead of fitting it (``-1``: LL -0.99, replay 5.8 m at 0.3 s decisions). Files
written before these options load with the settings they meant (:data:`LEGACY_CONFIG`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, Field, field_validator

from irl.domains.merge.actions import N_ACTIONS, action_of
from irl.errors import ConfigError, DemonstrationError, ModelFileError
from irl.planning.decisions import PlanningDecisions, split_groups
from irl.planning.features import DEFAULT_LENGTH_FT, Shape, fit_shape
from irl.planning.fit import fit_planner, select
from irl.planning.model import LIKELIHOOD_ROAD_MODEL, PathTensors, PlannerConfig, first_step, path_tensors
from irl.planning.policy import bin_log_policy_of_fine, fine_log_policy
from merge_irl.atomic import write_json_atomic
from merge_irl.json_file import STRICT, dataclass_schema, read_json_object, to_dataclass, validate
from merge_irl.units import FT_PER_M

#: The ``format`` field of a planner file.
PLANNER_FORMAT = "merge-irl-planner/1"
#: Keys of the file's ``config`` that older files lack, with the values those files meant (a
#: fitted jerk weight was then always part of the reward; the current default has none).
LEGACY_CONFIG: dict[str, Any] = {"jerk": True, "free_road": False, "lag": 1.0, "v0_ft_s": 0.0, "jerk_weight": None,
                                 "gap_track": False, "temperature": 1.0, "road_model": "legacy",
                                 "c_brake_ft_s2": 4.5 * FT_PER_M, "margin_ft": 1.0 * FT_PER_M}
OPTIONAL_CONFIG_KEYS = frozenset(LEGACY_CONFIG)


@dataclass(frozen=True)
class PlanningDriver:
    """A planning driver with learned reward weights.

    Attributes:
        theta: ``[K]`` weights of ``feature_names``; feature_names: ``config.feature_names``;
        config: the planner's settings; shape: the features' shape (fitted on the training
        decisions); decision_step_s: seconds per decision; action_acc_ft_s2: ``[5]`` mean
        acceleration of each paper action in training (ft/s^2; the later tree segments' values
        and for reporting); loglik: training log-likelihood (nats); converged: the fit's
        optimiser reported success; info: provenance (selection trials, grad norm, ...).

    Raises:
        ConfigError: ``theta`` or ``feature_names`` that do not match ``config``, a step other
            than the config's, or ``action_acc_ft_s2`` not 5 finite numbers.
    """

    theta: np.ndarray
    feature_names: tuple[str, ...]
    config: PlannerConfig
    shape: Shape
    decision_step_s: float
    action_acc_ft_s2: tuple[float, ...]
    loglik: float = float("nan")
    converged: bool = True
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        theta = np.asarray(self.theta, dtype=np.float64)
        object.__setattr__(self, "theta", theta)
        object.__setattr__(self, "feature_names", tuple(self.feature_names))
        object.__setattr__(self, "action_acc_ft_s2", tuple(float(x) for x in self.action_acc_ft_s2))
        if self.feature_names != self.config.feature_names or theta.shape != (len(self.feature_names),) \
                or not np.all(np.isfinite(theta)):
            raise ConfigError(f"PlanningDriver: theta must be {len(self.config.feature_names)} finite weights of "
                              f"{self.config.feature_names}, got {theta.shape} of {self.feature_names}")
        if abs(self.decision_step_s - self.config.decision_step_s) > 1e-9:
            raise ConfigError(f"PlanningDriver: decision_step_s {self.decision_step_s} != the config's "
                              f"{self.config.decision_step_s}")
        if len(self.action_acc_ft_s2) != N_ACTIONS or not all(map(math.isfinite, self.action_acc_ft_s2)):
            raise ConfigError(f"PlanningDriver: action_acc_ft_s2 must be {N_ACTIONS} finite numbers")

    @property
    def fine_grid(self) -> np.ndarray:
        """``[G]`` the accelerations the driver chooses among (ft/s^2)."""
        return self.config.fine_grid(np.asarray(self.action_acc_ft_s2))

    def tensors(self, obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray,
                b_merged: np.ndarray | None = None) -> PathTensors:
        """Path tensors of observations ``obs [N, 7]``, ``prev_acc [N]``, ``acc_C [N]`` (and
        ``b_merged [N]``: B in A's lane, :func:`~.model.path_tensors`): the features of the
        driver's nonzero weights only (the others are 0 and weigh nothing)."""
        need = frozenset(n for n, w in zip(self.feature_names, self.theta) if w != 0.0)
        return path_tensors(obs, prev_acc, acc_C, self.action_acc_ft_s2, self.shape, self.config, need=need,
                            b_merged=b_merged)

    def fine_log_policy(self, obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray,
                        b_merged: np.ndarray | None = None) -> np.ndarray:
        """``[N, G]`` ``log pi(g | x)`` over the fine grid."""
        return fine_log_policy(self.tensors(obs, prev_acc, acc_C, b_merged), self.theta, self.config.backup,
                               self.config.collision_penalty, self.config.temperature)

    def bin_log_policy(self, obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray) -> np.ndarray:
        """``[N, 5]`` ``log P(b | x)`` over the paper actions (``-inf``: no fine action in the bin)."""
        T = self.tensors(obs, prev_acc, acc_C)
        return bin_log_policy_of_fine(fine_log_policy(T, self.theta, self.config.backup,
                                                      self.config.collision_penalty, self.config.temperature), T.bins)

    def applied(self, choice: np.ndarray, prev_acc: np.ndarray) -> np.ndarray:
        """``[N]`` the accelerations A applies for fine choices ``choice [N]`` after ``prev_acc
        [N]`` (ft/s^2): the choices themselves, or under an actuation lag ``k``
        (:attr:`~.model.PlannerConfig.lag`) ``(1 - k) prev_acc + k choice`` (NaN -> 0)."""
        choice = np.asarray(choice, dtype=np.float64)
        if self.config.lag >= 1.0:
            return choice
        prev = np.nan_to_num(np.asarray(prev_acc, dtype=np.float64), nan=0.0)
        return (1.0 - self.config.lag) * prev + self.config.lag * choice

    def act(self, obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray,
            b_merged: np.ndarray | None = None) -> np.ndarray:
        """``[N]`` the acceleration A applies for the most likely fine action of each observation
        (ft/s^2; :meth:`applied`): the driver's decision rule, the one its replay fit selects and
        the closed loop drives by. ``b_merged [N]``: B in A's lane (None: not known)."""
        lp = self.fine_log_policy(obs, prev_acc, acc_C, b_merged)
        return self.applied(self.fine_grid[np.argmax(lp, axis=1)], prev_acc)

    def choose(self, obs_row, prev_acc: float = 0.0, acc_C: float = 0.0,
               mode: bool | np.random.Generator = True) -> tuple[int, float]:
        """``(paper action, acceleration ft/s^2)`` of one observation ``[7]``: the most likely
        fine action (``mode=True``) or one drawn with the generator ``mode``, as applied
        (:meth:`applied`)."""
        lp = self.fine_log_policy(np.asarray(obs_row, dtype=np.float64).reshape(1, -1), np.array([prev_acc]),
                                  np.array([acc_C]))[0]
        if mode is True:
            g = int(np.argmax(lp))
        elif isinstance(mode, np.random.Generator):
            p = np.exp(lp)
            g = int(mode.choice(lp.size, p=p / p.sum()))
        else:
            raise ConfigError(f"choose: mode must be True or a numpy Generator, got {mode!r}")
        acc = float(self.applied(self.fine_grid[g:g + 1], np.array([prev_acc]))[0])
        return action_of(acc), acc

    def step_reward(self, obs: np.ndarray, prev_acc: np.ndarray, acc_C: np.ndarray, acc: np.ndarray) -> np.ndarray:
        """``[N]`` the learned reward of one decision step: ``theta . phi`` of the step that applies
        ``acc [N]`` (ft/s^2) from observations ``obs [N, 7]`` (with ``prev_acc [N]`` and C's
        ``acc_C [N]``, ft/s^2), plus ``collision_penalty`` times its collision count (``first_step``):
        the first step of every path the planner scores (:func:`~.model.path_tensors`)."""
        obs = np.asarray(obs, dtype=np.float64).reshape(-1, 7)
        acc = np.asarray(acc, dtype=np.float64).reshape(-1)
        phi, col = first_step(obs, np.asarray(prev_acc, dtype=np.float64).reshape(-1),
                              np.asarray(acc_C, dtype=np.float64).reshape(-1), acc, self.shape, self.config)
        return phi @ self.theta + self.config.collision_penalty * col

    def heldout_ll_per_decision(self, decisions: PlanningDecisions) -> float:
        """Mean ``log P(b | x)`` of ``decisions`` (nats per decision)."""
        lp = self.bin_log_policy(decisions.obs, decisions.prev_acc, decisions.acc_C)
        return float(lp[np.arange(decisions.n), decisions.actions].mean())

    def to_json_dict(self) -> dict[str, Any]:
        """The file's JSON object (format :data:`PLANNER_FORMAT`; a non-finite ``loglik`` as null)."""
        return {"format": PLANNER_FORMAT, "feature_names": list(self.feature_names), "theta": self.theta.tolist(),
                "config": asdict(self.config), "shape": self.shape.as_dict(), "decision_step_s": self.decision_step_s,
                "action_acc_ft_s2": list(self.action_acc_ft_s2), "fine_grid_ft_s2": self.fine_grid.tolist(),
                "loglik": self.loglik if math.isfinite(self.loglik) else None, "converged": self.converged,
                "info": self.info}

    def save(self, path: str | os.PathLike) -> Path:
        """Write the JSON file atomically (:func:`merge_irl.atomic.write_json_atomic`)."""
        return write_json_atomic(path, self.to_json_dict())

    @classmethod
    def load(cls, path: str | os.PathLike) -> PlanningDriver:
        """Read a planner file.

        Raises:
            ModelFileError: missing, unreadable, another format, or a malformed field (one line
                naming the file and the field path).
        """
        return cls.from_json_dict(read_json_object(path, what="planner file", error=ModelFileError), Path(path))

    @classmethod
    def from_json_dict(cls, data: Any, source: str | os.PathLike = "<dict>") -> PlanningDriver:
        """The driver of a parsed planner file object (:meth:`to_json_dict`'s layout), validated
        by :class:`PlannerFileSchema`; ``source`` names it in messages.

        Raises:
            ModelFileError: as :meth:`load`.
        """
        m = validate(PlannerFileSchema, data, source, error=ModelFileError)
        try:
            config = to_dataclass(PlannerConfig, m.config)
        except (ConfigError, TypeError) as e:
            raise ModelFileError(f"{source}: {_field_problems('config', e, PlannerConfig)}") from None
        try:
            shape = to_dataclass(Shape, m.shape)
        except (ConfigError, TypeError) as e:
            raise ModelFileError(f"{source}: {_field_problems('shape', e, Shape)}") from None
        if m.feature_names != list(config.feature_names):
            raise ModelFileError(f"{source}: feature_names: must be {list(config.feature_names)} for its config")
        try:
            return cls(np.asarray(m.theta, dtype=np.float64), tuple(m.feature_names), config, shape, m.decision_step_s,
                       tuple(m.action_acc_ft_s2), math.nan if m.loglik is None else m.loglik, m.converged,
                       dict(m.info or {}))
        except ConfigError as e:
            raise ModelFileError(f"{source}: theta, decision_step_s or action_acc_ft_s2: {e}") from None


Finite = Annotated[float, Field(allow_inf_nan=False)]
#: ``config``: :class:`PlannerConfig`'s fields, those of :data:`LEGACY_CONFIG` optional.
PlannerConfigSchema = dataclass_schema(PlannerConfig, optional=LEGACY_CONFIG)
#: ``shape``: every :class:`Shape` field.
ShapeSchema = dataclass_schema(Shape, optional={})


class PlannerFileSchema(BaseModel):
    """The schema of a planner file (format :data:`PLANNER_FORMAT`)."""

    model_config = STRICT

    format: Any = Field(default=None, validate_default=True)
    feature_names: list[str]
    theta: list[Finite] = Field(min_length=1)
    config: PlannerConfigSchema  # type: ignore[valid-type]  # built from the dataclass
    shape: ShapeSchema  # type: ignore[valid-type]
    decision_step_s: Finite
    action_acc_ft_s2: list[Finite] = Field(min_length=N_ACTIONS, max_length=N_ACTIONS)
    loglik: Finite | None = Field(default=None, le=0)
    converged: bool = True
    info: dict[str, Any] | None = None

    @field_validator("format")
    @classmethod
    def _this_format(cls, fmt: Any) -> Any:
        if fmt != PLANNER_FORMAT:
            raise ValueError(f"expected format {PLANNER_FORMAT!r}, got {fmt!r}")
        return fmt


def _field_problems(field: str, error: Exception, kind: type) -> str:
    """A settings class's message (``"PlannerConfig: gamma must be ...; depth must be ..."``) as
    field paths of the file (``"config.gamma: must be ...; config.depth: must be ..."``)."""
    text = str(error)
    head, sep, rest = text.partition(": ")
    problems = rest.split("; ") if sep and head.isidentifier() else [text]
    out = []
    for problem in problems:
        name, space, what = problem.partition(" ")
        known = name in {f.name for f in fields(kind)}
        out.append(f"{field}.{name}: {what}" if space and known else f"{field}: {problem}")
    return "; ".join(out)


def shape_of(decisions: PlanningDecisions) -> Shape:
    """The feature shape fitted on ``decisions`` (:func:`~irl.planning.features.fit_shape`)."""
    len_C = np.where(np.isfinite(decisions.obs[:, 5]), decisions.obs[:, 5], DEFAULT_LENGTH_FT)
    return fit_shape(decisions.obs[:, 0] - len_C, decisions.obs[:, 4], decisions.obs[:, 1], decisions.acc)


def shape_for(shape: Shape, config: PlannerConfig) -> Shape:
    """``shape`` with the config's desired speed (:attr:`~.model.PlannerConfig.v0_ft_s`) when set."""
    return replace(shape, v0_ft_s=float(config.v0_ft_s)) if config.v0_ft_s > 0 else shape


def learn_planning_driver(decisions: PlanningDecisions, *, seed: int = 0,
                          selection: PlannerConfig | str = "heldout", l2: float = 0.1, select_cap: int = 12000,
                          select_options: dict[str, Any] | None = None, base: PlannerConfig | None = None,
                          log: Callable[[str], None] = lambda s: None) -> PlanningDriver:
    """Learn a planning driver on ``decisions``.

    ``selection="heldout"``: the settings by :func:`~irl.planning.fit.select` on an inner 70/30 split of the
    groups (``seed``), the fitting part capped at about ``select_cap`` decisions by drawing whole
    groups (``seed + 1``); a :class:`~irl.planning.model.PlannerConfig`: that setting. Then the weights are
    fitted on all ``decisions`` (L2 ``l2``). The shape and the paper actions' accelerations come
    from all ``decisions`` (the desired speed the config's when it sets one, :func:`shape_for`).
    ``base``: the settings the selection starts from (default :class:`~irl.planning.model.PlannerConfig`'s
    with the road model :data:`~irl.planning.model.LIKELIHOOD_ROAD_MODEL`, at the decisions' step).

    Raises:
        ConfigError: an unknown ``selection``, or a config of another decision step.
        DemonstrationError: fewer than 2 groups (followers) to select on (the message names
            ``--no-selection``).
    """
    acc5 = decisions.action_acc_ft_s2()
    shape = shape_of(decisions)
    trials: list[dict[str, Any]] = []
    if isinstance(selection, PlannerConfig):
        config = selection
    elif selection == "heldout":
        n_groups = int(np.unique(decisions.groups).size)
        if n_groups < 2:  # said in the user's words, not split_groups'
            raise DemonstrationError(
                f"the held-out selection of the planner's settings needs demonstrations of at least 2 followers "
                f"(pair files or merge encounters of distinct cars), got {n_groups}: give more data, or fit the "
                "default settings without selection (learn-driver --no-selection; selection=PlannerConfig())")
        fi, va = split_groups(decisions.groups, 0.3, seed)
        fit_idx, val_idx = np.flatnonzero(fi), np.flatnonzero(va)
        if fit_idx.size > select_cap:
            g = np.random.default_rng(seed + 1).permutation(np.unique(decisions.groups[fit_idx]))
            sizes = np.array([(decisions.groups[fit_idx] == x).sum() for x in g])
            keep = g[: int(np.searchsorted(np.cumsum(sizes), select_cap)) + 1]
            fit_idx = fit_idx[np.isin(decisions.groups[fit_idx], keep)]
        dfit, dval = decisions.take(fit_idx), decisions.take(val_idx)
        cache: dict[tuple[Any, str], PathTensors] = {}

        def build(cfg: PlannerConfig, which: str) -> PathTensors:
            key = (replace(cfg, backup="avg"), which)  # the backup does not change the paths
            if key not in cache:
                for k in [k for k in cache if k[0] != key[0]]:
                    del cache[k]
                d = dfit if which == "fit" else dval
                cache[key] = path_tensors(d.obs, d.prev_acc, d.acc_C, acc5, shape_for(shape, cfg), cfg)
            return cache[key]

        base = replace(base or PlannerConfig(road_model=LIKELIHOOD_ROAD_MODEL), decision_step_s=decisions.decision_step_s)
        config, tr = select(build, dfit.actions, dval.actions, base=base, l2=l2, log=log, **(select_options or {}))
        cache.clear()
        trials = [{**asdict(t.config), "val_ll": t.val_ll, "train_ll": t.train_ll, "converged": t.converged}
                  for t in tr]
    else:
        raise ConfigError(f"selection must be 'heldout' or a PlannerConfig, got {selection!r}")
    if abs(config.decision_step_s - decisions.decision_step_s) > 1e-9:
        raise ConfigError(f"config decision step {config.decision_step_s} s != the decisions' "
                          f"{decisions.decision_step_s} s")
    shape = shape_for(shape, config)
    T = path_tensors(decisions.obs, decisions.prev_acc, decisions.acc_C, acc5, shape, config)
    fit = fit_planner(T, decisions.actions, config, l2=l2)
    info = {"n_decisions": decisions.n, "l2": l2, "seed": seed, "grad_norm": fit.grad_norm, "n_iter": fit.n_iter,
            "selection": trials}
    return PlanningDriver(fit.theta, config.feature_names, config, shape, decisions.decision_step_s, acc5,
                          fit.loglik, fit.converged, info)
