"""The drivers of a closed-loop evaluation from their files, and distinct names for all.

Used by :func:`analysis.evaluation.plan.plan_evaluation`. A learned file becomes a driver through
the driver-format registry (:mod:`sim.drivers.formats`); the baselines are the registry of
:mod:`sim.drivers.baselines`.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Sequence
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


def check_unambiguous(own: Sequence[Policy], others: Sequence[Policy]) -> None:
    """Refuse names that would leave a report's rows, recordings and ``--fail-if`` ambiguous:
    one of ``own`` (the caller's policies, e.g. ``--policy``/``--driver``/``--cf-model``) named as
    one of ``others`` (the learned models and baselines of the same evaluation), or two of ``own``
    of different origin (``spec`` or ``source``) under one name. The same policy given twice is
    numbered by :func:`with_distinct_names` as before.

    Raises:
        PolicyError: one line naming both origins and the fix (a NAME of its own).
    """
    taken = {p.name: p for p in others}
    seen: dict[str, Policy] = {}
    for p in own:
        origin = _origin(p)
        if p.name in taken:
            o = taken[p.name]
            what = "the baseline" if not _origin(o) else f"the model {_origin(o)}"
            raise PolicyError(
                f"{origin or 'a policy'}: its name {p.name!r} is also {what} {p.name!r} of this evaluation; the report, "
                f"the recordings and --fail-if could not tell them apart: give it a name of its own "
                f"(--policy MODULE:CALLABLE:NAME, e.g. {p.name}-mine; --driver: rename the file)")
        first = seen.setdefault(p.name, p)
        if first is not p and _origin(first) != origin:
            raise PolicyError(
                f"two policies are named {p.name!r}: {_origin(first) or 'one'} and {origin or 'another'}; the report "
                "could not tell which is which: give each a name of its own (--policy MODULE:CALLABLE:NAME)")


def _origin(p: Policy) -> str:
    spec = getattr(p, "spec", "") or ""
    return spec or str(getattr(p, "source", "") or "")


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


def check_picklable(pols: Sequence[Policy], executor: str) -> None:
    """Refuse, before any work, a policy that the ``executor``'s workers cannot receive.

    Worker processes (``process``, ``dask-local``, ``dask://``) are fresh Python processes: each
    policy reaches them pickled, and a policy built from a callable object (not from a
    ``module:callable`` spec) is pickled with its callable. A lambda, a function defined inside
    another, or an object holding a lock or an open file cannot be (Dask's cloudpickle takes
    lambdas and closures, not locks or files). ``serial`` needs no pickling.

    Raises:
        PolicyError: one line naming the policy, the pickling error, why the workers need it and
            the fixes (a module-level function, ``CallablePolicy.from_spec("file.py:fn")``, or
            ``executor="serial"`` / ``--executor serial``).
    """
    if executor.strip() == "serial":
        return
    dask = executor.startswith(("dask", "tls"))
    for p in pols:
        err = _pickle_error(p, dask)
        if err is None:
            continue
        fn = getattr(p, "fn", None)
        what = f"its callable {getattr(fn, '__qualname__', type(fn).__name__)!r}" if fn is not None else \
            f"the {type(p).__name__} object"
        raise PolicyError(
            f"policy {p.name!r} cannot be sent to the worker processes of --executor {executor} ({err}): workers are "
            f"fresh Python processes that receive each policy pickled, and {what} does not pickle (a lambda, a "
            "function defined inside another, an object holding a lock or an open file). Fix: define it as a "
            "module-level function and give it as module:callable (--policy, CallablePolicy.from_spec(\"file.py:fn\")), "
            "which workers import again, or run in this process with --executor serial (executor=\"serial\")")


def _pickle_error(p: Policy, dask: bool) -> str | None:
    """The pickling error of ``p`` in one line, or None when it pickles (with cloudpickle too under Dask)."""
    try:
        pickle.dumps(p)
        return None
    except Exception as e:  # noqa: BLE001 - pickle raises PicklingError, TypeError, AttributeError
        first = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    if dask:
        try:
            import cloudpickle  # type: ignore[import-untyped]

            cloudpickle.dumps(p)
            return None
        except ImportError:  # pragma: no cover - Dask brings cloudpickle
            pass
        except Exception as e:  # noqa: BLE001
            first = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    return first


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
