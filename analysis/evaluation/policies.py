"""The drivers of a closed-loop evaluation from their files, and distinct names for all.

Used by :func:`analysis.evaluation.evaluate.evaluate`. A learned file becomes a driver through
the driver-format registry (:mod:`sim.drivers.formats`); the baselines are the registry of
:mod:`sim.drivers.baselines`.
"""

from __future__ import annotations

import os
from dataclasses import is_dataclass, replace
from pathlib import Path

from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.result import SavedModel
from sim.drivers.formats import driver_policy
from sim.drivers.learned import CarFollowingLogitPolicy, LearnedPolicy
from sim.drivers.policy import Policy, PolicyError


def learned_policy(model: SavedModel | str | os.PathLike, name: str = "") -> LearnedPolicy:
    """A :class:`LearnedPolicy` from a saved tabular model (path or object) with its bin edges;
    a path is read through the driver-format registry as a ``--model`` file.

    Raises:
        ModelFileError: ``model`` is a path to a missing, unreadable or malformed ``model.json``,
            or to a driver's file (which option takes it named).
        PolicyError: the model is not a merge model (message prefixed with the file).
    """
    if isinstance(model, SavedModel):
        return LearnedPolicy.from_model(model, name=name or model.method)
    pol = driver_policy(model, name, role="model", option="--model")
    if not isinstance(pol, LearnedPolicy):  # a registered format of role "model" that builds another policy
        raise PolicyError(f"{model}: a model of role 'model' must build a tabular LearnedPolicy, got {type(pol).__name__}")
    return pol


def cf_policy(path: str | os.PathLike, name: str = "") -> CarFollowingLogitPolicy:
    """A :class:`~sim.drivers.learned.CarFollowingLogitPolicy` from a car-following logit file
    (``cf-dagger.json`` or ``cf-logit.json`` of ``merge-irl dagger``; ``evaluate --cf-model``),
    named ``name`` or the file's stem. A fit that did not converge is flagged (``not_converged``).

    Raises:
        ModelFileError: a missing, unreadable or malformed file, or another format.
    """
    return CarFollowingLogitPolicy(CarFollowingLogit.load(path), name=name or Path(path).stem, source=str(path))


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


#: Names this module held until 2026-12-05 and their homes now (docs/changelog.md): importing one
#: fails with one line naming its home, no silent alias.
MOVED_NAMES = {
    **dict.fromkeys(("BASELINES", "Baseline", "BaselineContext", "register_baseline", "default_baselines",
                     "check_baselines", "baseline_drivers", "left_out_baselines", "training_action_acc"),
                    "sim.drivers.baselines"),
    **dict.fromkeys(("load_driver", "driver_policy", "policy_callable"), "sim.drivers.formats"),
    "driver_format": "sim.drivers.formats (as format_field)",
}


def __getattr__(name: str):
    if name in MOVED_NAMES:
        raise ImportError(f"analysis.evaluation.policies.{name} moved to {MOVED_NAMES[name]} "
                          "(see docs/changelog.md)", name=name)
    raise AttributeError(f"module 'analysis.evaluation.policies' has no attribute {name!r}")
