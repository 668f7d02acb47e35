"""The baseline drivers, by name: one registry (:data:`BASELINES`, name -> :class:`Baseline`: a
factory of a :class:`BaselineContext`, whether it needs training encounters, whether it runs by
default). The trivial baselines (uniform, the training demonstrations' action frequencies,
markov, behaviour cloning) beside SUMO's own driver by default, plus two references on request
(``idm``, ``sumo-in-lane``). A new baseline is one :func:`register_baseline` call;
``merge-irl evaluate`` (its default set and ``--baselines``) and the reports read the registry.
(:data:`irl.baselines.TABULAR_BASELINES` are the paper tables' leave-one-out baselines, another
thing.)
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import pandas as pd

from irl.baselines import fit_baseline
from irl.demonstrations import Demonstrations
from irl.domains.merge.actions import ACTION_ACC_FT_S2, actions_of
from irl.domains.merge.bins import MergeBins, fit_quantile_bins
from irl.domains.merge.encounters import prepare_encounters
from irl.domains.merge.mdp import action_mean_acc, discretize, read_encounters
from merge_irl.registry import Registry, RegistryError
from sim.drivers.idm import IdmPolicy
from sim.drivers.learned import BaselineTabularPolicy
from sim.drivers.policy import Policy, PolicyError, SumoPolicy, UniformPolicy
from sim.errors import SimError


@dataclass(frozen=True, eq=False)
class BaselineContext:
    """What a baseline's factory may need, read lazily (a baseline that needs nothing reads nothing).

    Attributes:
        spec: the scenario (:class:`scenarios.spec.model.ScenarioSpec`) the drivers run in.
        decision_step_s: the evaluation's decision step (s).
        train_demos: the training encounters (Parquet/CSV path or DataFrame); None: none given.
        bins: the paper state bins of the fitted baselines (the first model's); None: quantile
            bins fitted on the training encounters.
    """

    spec: Any
    decision_step_s: float
    train_demos: str | os.PathLike | pd.DataFrame | None = None
    bins: MergeBins | None = None

    @property
    def where(self) -> str:
        """The training encounters' name in errors."""
        return str(self.train_demos) if isinstance(self.train_demos, (str, os.PathLike)) else "training encounters"

    @cached_property
    def training(self) -> pd.DataFrame:
        """The training encounter frames, prepared.

        Raises:
            PolicyError: no training encounters were given.
            DemonstrationError: they cannot be read.
        """
        if self.train_demos is None:
            raise PolicyError("this baseline needs training encounters (train_demos / --train-demos)")
        return _training_table(self.train_demos)

    @cached_property
    def training_bins(self) -> MergeBins:
        """:attr:`bins`, else quantile bins fitted on the training encounters."""
        return self.bins if self.bins is not None else fit_quantile_bins(self.training, where=self.where)

    @cached_property
    def demos(self) -> Demonstrations:
        """The training encounters discretized in :attr:`training_bins` at :attr:`decision_step_s`.

        Raises:
            DemonstrationError: they cannot be read or discretized.
        """
        return discretize(self.training, self.training_bins, where=self.where, decision_step_s=self.decision_step_s)

    @cached_property
    def action_acc_ft_s2(self) -> tuple[float, ...]:
        """``[5]`` acceleration (ft/s^2) a baseline applies per action: the training frames' mean
        per action bin (as :func:`training_action_acc`), else the bins' midpoints."""
        if self.train_demos is None:
            return tuple(float(x) for x in ACTION_ACC_FT_S2)
        acc = self.training["acc_A"].to_numpy(float)
        return action_mean_acc(acc, actions_of(acc))


@dataclass(frozen=True)
class Baseline:
    """A baseline driver of the evaluation, registered by name (:func:`register_baseline`).

    Attributes:
        name: its name (``--baselines``, reports); the factory's policy is named so.
        factory: ``context -> Policy`` (:class:`BaselineContext`).
        fitted: needs training encounters (left out, and said so in report.md, without them).
        default: in the default set of :func:`analysis.evaluation.evaluate.evaluate`.
        help: one line for users.
    """

    name: str
    factory: Callable[[BaselineContext], Policy]
    fitted: bool = False
    default: bool = False
    help: str = ""


class BaselineRegistryError(RegistryError, PolicyError):
    """A baseline registered twice or without a name, or an unknown one (a :class:`PolicyError`)."""


#: The baselines, by name, in their order (:func:`register_baseline`): SUMO's own driver, uniform
#: random, and the tabular baselines of :mod:`irl.baselines` fitted on the training demonstrations
#: by default, and two references on request.
BASELINES: Registry[Baseline] = Registry("baseline", error=BaselineRegistryError)


def register_baseline(baseline: Baseline) -> Baseline:
    """Add ``baseline`` to :data:`BASELINES` (after the others); returns it.

    Raises:
        PolicyError (BaselineRegistryError): a baseline of that name is registered already.
    """
    BASELINES.register(baseline.name, baseline)
    return baseline


def default_baselines() -> tuple[str, ...]:
    """The names of the baselines every evaluation runs unless told otherwise, in order."""
    return tuple(b.name for b in BASELINES.values() if b.default)


def check_baselines(names: Sequence[str], where: str = "evaluate") -> None:
    """Refuse a name that is not a registered baseline.

    Raises:
        SimError: an unknown name (the known ones listed).
    """
    bad = [b for b in names if b not in BASELINES]
    if bad:
        raise SimError(f"{where}: unknown baseline(s) {bad}; expected some of {', '.join(BASELINES)}")


def _tabular(name: str) -> Callable[[BaselineContext], Policy]:
    def make(ctx: BaselineContext) -> Policy:
        return BaselineTabularPolicy(fit_baseline(name, ctx.demos), ctx.training_bins, name,
                                     action_acc_ft_s2=ctx.action_acc_ft_s2, decision_step_s=ctx.decision_step_s)
    return make


def _idm(ctx: BaselineContext) -> Policy:
    if ctx.train_demos is None:
        warnings.warn("evaluate: idm without training encounters applies the action bins' midpoints "
                      f"{tuple(ACTION_ACC_FT_S2)} ft/s^2 (High Brake too weak to stop behind a braking car; "
                      "give train_demos / --train-demos)", UserWarning, stacklevel=4)
    return IdmPolicy.from_scenario(ctx.spec, action_acc_ft_s2=ctx.action_acc_ft_s2)


register_baseline(Baseline("sumo", lambda ctx: SumoPolicy(), default=True,
                           help="SUMO's own car-following model drives A (not taken over)"))
register_baseline(Baseline("uniform", lambda ctx: UniformPolicy(), default=True,
                           help="the five actions uniformly at random"))
register_baseline(Baseline("marginal", _tabular("marginal"), fitted=True, default=True,
                           help="the training demonstrations' action frequencies"))
register_baseline(Baseline("markov", _tabular("markov"), fitted=True, default=True,
                           help="the training demonstrations' action given A's previous action"))
register_baseline(Baseline("bc", _tabular("bc"), fitted=True, default=True,
                           help="behaviour cloning: the training demonstrations' action given the paper state"))
register_baseline(Baseline("idm", _idm,
                           help="the Intelligent Driver Model with the scenario's car parameters, driven through "
                                "the controller (sim.drivers.idm.IdmPolicy)"))
register_baseline(Baseline("sumo-in-lane", lambda ctx: SumoPolicy("sumo-in-lane", keep_lane=True),
                           help="SUMO's driver with A's lane changes off while observed, as for every commanded "
                                "driver"))


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


def baseline_drivers(baselines: Sequence[str], spec, train_demos, bins: MergeBins | None,
                     decision_step_s: float) -> list[Policy]:
    """The drivers of ``baselines`` (names of :data:`BASELINES`, in the order given), each of
    its factory with one :class:`BaselineContext`; the fitted ones left out without training
    encounters.

    Raises:
        SimError: an unknown name.
        PolicyError: a factory's policy is not named as its baseline.
        DemonstrationError: the training encounters cannot be read or discretized.
    """
    check_baselines(baselines)
    ctx = BaselineContext(spec, decision_step_s, train_demos, bins)
    pols: list[Policy] = []
    for name in baselines:
        b = BASELINES[name]
        if b.fitted and train_demos is None:
            continue
        p = b.factory(ctx)
        if p.name != b.name:
            raise PolicyError(f"baseline {b.name!r}: its factory made a policy named {p.name!r}")
        pols.append(p)
    return pols


def left_out_baselines(baselines: Sequence[str], train_demos) -> list[str]:
    """The fitted ones of ``baselines``, when there are no training encounters (else none)."""
    return [b for b in baselines if BASELINES[b].fitted and train_demos is None]
