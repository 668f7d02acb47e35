"""Driver specs to drivers: one list, one resolver, through the driver-format registry.

A driver spec (:data:`analysis.evaluation.config.DriverSpec`) is one of

- a learned file of any registered format (:mod:`sim.drivers.formats`: a tabular IRL model, a
  car-following logit, a planning driver, or a format registered by one's own code), read by
  :func:`sim.drivers.formats.driver_policy` and named after the file's stem (a tabular model:
  after its method);
- a baseline name (:data:`sim.drivers.baselines.BASELINES`: ``sumo``, ``uniform``, ``idm``, ...);
- a :class:`~irl.result.SavedModel` object;
- a :class:`~sim.drivers.policy.Policy` object, used as it is;
- a callable ``obs -> action`` (or an object with Stable-Baselines3's ``predict``), wrapped as a
  :class:`sim.drivers.callables.CallablePolicy`.

``merge-irl evaluate --driver`` takes the file and baseline specs (``--model`` and ``--cf-model``
are deprecated aliases of it); ``--policy MODULE:CALLABLE`` builds callable specs.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from analysis.evaluation.config import DriverSpec
from analysis.evaluation.policies import learned_policy
from irl.errors import ModelFileError
from irl.result import SavedModel
from sim.drivers.baselines import BASELINES
from sim.drivers.callables import CallablePolicy
from sim.drivers.formats import FORMATS, driver_policy, family_of, format_field
from sim.drivers.learned import LearnedPolicy
from sim.drivers.policy import Policy, PolicyError


@dataclass(frozen=True)
class ResolvedDriver:
    """One driver spec, resolved.

    Attributes:
        policy: the closed-loop driver.
        file: the learned file it was read from (as given), or None (an object, a callable).
        model: True for a tabular IRL model (a ``SavedModel`` or a file of a ``model`` role format).
    """

    policy: Policy
    file: str | os.PathLike[str] | None = None
    model: bool = False


@dataclass(frozen=True)
class ResolvedSpecs:
    """The drivers of a spec list: ``models`` and ``others`` in the order given, ``baselines``
    the baseline names among the specs (in order, each once)."""

    models: tuple[ResolvedDriver, ...]
    others: tuple[ResolvedDriver, ...]
    baselines: tuple[str, ...]


def resolve_driver_specs(specs: Sequence[DriverSpec], *, option: str = "--driver") -> ResolvedSpecs:
    """Every spec of ``specs`` as a driver (see the module docstring).

    Args:
        specs: driver specs, in order.
        option: the option the file specs came with, for messages.

    Raises:
        ModelFileError: a file that is missing, unreadable, malformed, or of no registered format
            (the known ones listed).
        PolicyError: a name that is both a baseline and an existing file; a model that is not a
            merge model. (An object that is neither a policy nor a callable is refused by the
            plan's :func:`sim.drivers.policy.check_policy`, naming what it lacks.)
    """
    models: list[ResolvedDriver] = []
    others: list[ResolvedDriver] = []
    baselines: list[str] = []
    for spec in specs:
        if isinstance(spec, str) and _is_baseline(spec):
            baselines += [] if spec in baselines else [spec]
            continue
        driver = resolve_driver_spec(spec, option=option)
        (models if driver.model else others).append(driver)
    return ResolvedSpecs(tuple(models), tuple(others), tuple(baselines))


def resolve_driver_spec(spec: DriverSpec, *, option: str = "--driver") -> ResolvedDriver:
    """One spec that is not a baseline name as a :class:`ResolvedDriver`.

    Raises:
        ModelFileError, PolicyError: see :func:`resolve_driver_specs`.
    """
    if isinstance(spec, SavedModel):
        return ResolvedDriver(learned_policy(spec), None, model=True)
    if isinstance(spec, (str, os.PathLike)):
        return _from_file(spec, option)
    if not any(hasattr(spec, m) for m in ("name", "controls", "probs")) and (
            callable(spec) or hasattr(spec, "predict")):
        return ResolvedDriver(CallablePolicy(spec))  # type: ignore[arg-type]  # a callable, checked above
    return ResolvedDriver(spec)  # type: ignore[arg-type]  # a Policy: check_policy names any member it lacks


def _is_baseline(spec: str) -> bool:
    if spec not in BASELINES:
        return False
    if Path(spec).exists():
        raise PolicyError(f"--driver {spec}: both the baseline {spec!r} and a file of that name; give the file as "
                          f"./{spec}, or the baseline through --baselines")
    return True


def _from_file(path: str | os.PathLike[str], option: str) -> ResolvedDriver:
    if not Path(path).exists() and not any(sep in str(path) for sep in ("/", "\\", ".")):
        raise ModelFileError(f"{option} {path}: neither a file nor a baseline name (baselines: "
                             f"{', '.join(BASELINES)})")
    if _role(path) == "model":  # a tabular model: its own checks (a merge model, a LearnedPolicy)
        return ResolvedDriver(learned_policy(path), path, model=True)
    pol = driver_policy(path, role=None, option=option)
    return ResolvedDriver(pol, path, model=isinstance(pol, LearnedPolicy))


def _role(path: str | os.PathLike[str]) -> str | None:
    try:
        fmt = FORMATS.get(family_of(format_field(path)))
    except ModelFileError:  # unreadable, no format: the loader names the fault
        return None
    return None if fmt is None else fmt.role
