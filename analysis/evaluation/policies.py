"""The drivers of a closed-loop evaluation: the baselines by name, learned IRL models and
car-following drivers from their files, and distinct names for all.

Used by :func:`analysis.evaluation.evaluate.evaluate`; the baselines are issue 11's (uniform, action
frequencies, markov, behaviour cloning beside SUMO's own driver), plus two references on request.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import is_dataclass, replace
from pathlib import Path

import pandas as pd

from analysis.evaluation.heldout_scoring import prepare_encounters
from irl.baselines import fit_baseline
from irl.domains.merge.actions import ACTION_ACC_FT_S2, actions_of
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.domains.merge.mdp import action_mean_acc, discretize, read_encounters
from irl.result import SavedModel
from sim.idm_policy import IdmPolicy
from sim.policy import (BaselineTabularPolicy, CarFollowingLogitPolicy, LearnedPolicy, Policy, PolicyError,
                        SumoPolicy, UniformPolicy)

#: Baselines of every evaluation (issue 11): SUMO's own driver, uniform random, and the
#: tabular baselines fitted on the training demonstrations (:mod:`irl.baselines`).
BASELINES = ("sumo", "uniform", "marginal", "markov", "bc")
#: Every baseline an evaluation can run: :data:`BASELINES` and, on request, ``idm``, the
#: Intelligent Driver Model with the scenario's car parameters through the controller
#: (:class:`sim.idm_policy.IdmPolicy`), and ``sumo-in-lane``, SUMO's driver with A's lane
#: changes switched off while observed (:class:`sim.policy.SumoPolicy` ``keep_lane``).
KNOWN_BASELINES = (*BASELINES, "idm", "sumo-in-lane")
#: The baselines that need training demonstrations.
FITTED_BASELINES = ("marginal", "markov", "bc")

_BASELINES: dict[str, Callable[[], Policy]] = {"sumo": SumoPolicy, "uniform": UniformPolicy,
                                               "sumo-in-lane": lambda: SumoPolicy("sumo-in-lane", keep_lane=True)}


def baseline_policies(names: Sequence[str], train_demos: str | os.PathLike | pd.DataFrame,
                      bins: MergeBins | None = None, decision_step_s: float = 0.3) -> list[BaselineTabularPolicy]:
    """The fitted baselines ``names`` (of ``FITTED_BASELINES``) from training encounters, in
    the paper state bins ``bins`` (None: quantile bins fitted on the training encounters).

    Raises:
        DemonstrationError: the training encounters cannot be read or discretized.
    """
    df = _training_table(train_demos)
    where = "training encounters" if isinstance(train_demos, pd.DataFrame) else str(train_demos)
    bins = bins if bins is not None else fit_quantile_bins(df, where=where)
    demos = discretize(df, bins, where=where, decision_step_s=decision_step_s)
    means = training_action_acc(df)
    return [BaselineTabularPolicy(fit_baseline(n, demos), bins, n, action_acc_ft_s2=means) for n in names]


def _training_table(train_demos: str | os.PathLike | pd.DataFrame) -> pd.DataFrame:
    df = train_demos if isinstance(train_demos, pd.DataFrame) else read_encounters(train_demos)
    return prepare_encounters(df, "training encounters" if isinstance(train_demos, pd.DataFrame) else str(train_demos))


def training_action_acc(train_demos: str | os.PathLike | pd.DataFrame) -> tuple[float, ...]:
    """``[5]`` the mean acceleration (ft/s^2) of each action bin over the frames of the training
    encounters (a bin without frames: its midpoint), as the baselines apply their actions.

    Raises:
        DemonstrationError: the training encounters cannot be read.
    """
    acc = _training_table(train_demos)["acc_A"].to_numpy(float)
    return action_mean_acc(acc, actions_of(acc))


def learned_policy(model: SavedModel | str | os.PathLike, name: str = "") -> LearnedPolicy:
    """A :class:`LearnedPolicy` from a saved model (path or object) with its bin edges.

    Raises:
        ModelFileError: ``model`` is a path to a missing, unreadable or malformed ``model.json``.
        PolicyError: the model is not a merge model (message prefixed with the file).
    """
    where = "model"
    if not isinstance(model, SavedModel):
        path = Path(model)
        model = SavedModel.load(path)
        name = name or path.stem
        where = str(path)
    try:
        return LearnedPolicy.from_model(model, name=name or model.method)
    except PolicyError as e:
        raise type(e)(f"{where}: {e}") from None


def cf_policy(path: str | os.PathLike, name: str = "") -> CarFollowingLogitPolicy:
    """A :class:`~sim.policy.CarFollowingLogitPolicy` from a car-following logit file
    (``cf-dagger.json`` or ``cf-logit.json`` of ``merge-irl dagger``), named ``name`` or the
    file's stem (as :func:`learned_policy` names a model file; the demo's ``cf-dagger`` is
    ``models/cf-dagger.json``). A fit that did not converge is flagged (``not_converged``).

    Raises:
        ModelFileError: a missing, unreadable or malformed file.
    """
    return CarFollowingLogitPolicy(CarFollowingLogit.load(path), name=name or Path(path).stem, source=str(path))


def baseline_drivers(baselines: Sequence[str], spec, train_demos, bins: MergeBins | None,
                     decision_step_s: float) -> list[Policy]:
    """The drivers of ``baselines`` (names of :data:`KNOWN_BASELINES`, in their order): the
    fitted ones from ``train_demos`` in ``bins`` (left out without training encounters), ``idm``
    of ``spec``'s car type with the training frames' action accelerations (warned about without
    them), the others as they are.

    Raises:
        DemonstrationError: the training encounters cannot be read or discretized.
    """
    pols: list[Policy] = []
    fitted = [b for b in baselines if b in FITTED_BASELINES]
    fitted_pols = baseline_policies(fitted, train_demos, bins, decision_step_s) \
        if fitted and train_demos is not None else []
    by_name = {p.name: p for p in fitted_pols}
    for b in baselines:
        if b in FITTED_BASELINES:
            if b in by_name:
                pols.append(by_name[b])
        elif b == "idm":  # applies its actions as the fitted baselines do, when there are training encounters
            if train_demos is None:
                warnings.warn("evaluate: idm without training encounters applies the action bins' midpoints "
                              f"{tuple(ACTION_ACC_FT_S2)} ft/s^2 (High Brake too weak to stop behind a braking car; "
                              "give train_demos / --train-demos)", UserWarning, stacklevel=3)
            acc = fitted_pols[0].action_acc_ft_s2 if fitted_pols else training_action_acc(train_demos) \
                if train_demos is not None else tuple(float(x) for x in ACTION_ACC_FT_S2)
            pols.append(IdmPolicy.from_scenario(spec, action_acc_ft_s2=acc))
        else:
            pols.append(_BASELINES[b]())
    return pols


def with_distinct_names(pols: list[Policy]) -> list[Policy]:
    """``pols`` with every repeated name numbered (``qavg-1``, ``qavg-2``).

    Raises:
        PolicyError: a policy with a repeated name is not a dataclass that can be renamed.
    """
    names = [p.name for p in pols]
    dup = {n for n in names if names.count(n) > 1}
    if not dup:
        return pols
    seen: dict[str, int] = {}
    renamed = []
    for p in pols:
        k = seen.get(p.name, 0)
        seen[p.name] = k + 1
        renamed.append(_renamed(p, f"{p.name}-{k + 1}") if p.name in dup else p)
    return renamed


def _renamed(p: Policy, name: str) -> Policy:
    if not is_dataclass(p) or isinstance(p, type):
        raise PolicyError(f"evaluate: two policies are named {p.name!r} and {type(p).__name__} is not a "
                          "dataclass that could be renamed; give each policy a distinct name")
    return replace(p, name=name)
