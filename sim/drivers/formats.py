"""The driver-format registry: every learned file a driver can be read from, by its ``format``.

A learned file is JSON with a ``format`` field ``"<family>/<version>"`` (``merge-irl-model/3``,
``merge-irl-cf-logit/2``, ``merge-irl-planner/1``). Each family registers one
:class:`DriverFormat` (:func:`register_format`): how to load its file, the closed-loop policy it
builds, its acceleration for replaying real car-following pairs
(``merge-irl calibrate evaluate --driver``) and its reward for the environment. Everything that
reads a learned file asks this registry, and only it reads the ``format`` field:
``merge-irl evaluate --driver`` (:func:`driver_policy`), ``calibrate evaluate --driver``
(:func:`replay_act`), the environment's ``reward=`` (:func:`driver_reward`), :func:`load_driver`
and :func:`policy_callable`.

The built-in formats are defined in their own modules (:mod:`sim.drivers.learned`: the tabular
IRL model and the car-following logit; :mod:`sim.drivers.planning`: the planning driver) and
registered here as ``"module:attr"`` entries of :data:`FORMATS`, imported when first read; a new
driver type is one module with its :class:`DriverFormat` and one entry here (or one
:func:`register_format` call from one's own code)::

    from sim.drivers.formats import DriverFormat, register_format
    register_format(DriverFormat("my-driver", "my driver (my-learn)", load=MyDriver.load,
                                 parse=MyDriver.from_json_dict,
                                 policy=lambda d, name, source: MyPolicy(d, name=name, source=source),
                                 replay_act=lambda d: (d.act, d.decision_step_s)))
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from irl.errors import ModelFileError
from irl.planning.replay import ActFn
from merge_irl.json_file import read_json
from merge_irl.registry import Registry, RegistryError

if TYPE_CHECKING:  # pragma: no cover
    from sim.drivers.callables import PolicyCallable
    from sim.drivers.observe import MergeObservation
    from sim.drivers.policy import Policy

#: ``reward(obs, action, acc_ft_s2) -> float`` of one decision in the environment.
RewardFn = Callable[["MergeObservation", int, float], float]
#: What a learned file is given as: a tabular IRL model (``--model``) or a driver (``--driver``).
Role = Literal["model", "driver"]


@dataclass(frozen=True)
class DriverFormat:
    """One family of learned files and what a driver of it does.

    Attributes:
        family: the ``format`` field's part before ``/`` (``"merge-irl-planner"``); files of any
            version of the family are this format's (its ``load`` refuses versions it cannot read).
        label: what the file is, for users (``"planning driver ('merge-irl learn-driver')"``).
        load: ``path -> the learned object`` (raises ``ModelFileError`` naming the file).
        parse: ``(data, path) -> the learned object`` from the file's parsed JSON object ``data``
            (``path`` for messages; raises ``ModelFileError``): the registry reads each file once
            and hands its content here; None: the registry calls ``load(path)`` instead.
        policy: ``(learned, name, source) -> Policy`` (:class:`sim.drivers.policy.Policy`): the
            closed-loop driver, named ``name``, read from ``source`` ("" when built in code).
        replay_act: ``learned -> (act, decision_step_s)``: its most likely acceleration when
            replaying real pairs (:data:`irl.planning.replay.ActFn`: ``act(obs [N, 7], prev_acc [N], acc_C [N]) -> [N]`` ft/s^2); None: the format does not replay pairs.
        reward: ``learned -> reward`` (:data:`RewardFn`) for the environment; None: no reward.
        role: ``"driver"`` (``evaluate --driver``) or ``"model"`` (``evaluate --model``).
    """

    family: str
    label: str
    load: Callable[[Path], Any]
    policy: Callable[[Any, str, str], Policy]
    replay_act: Callable[[Any], tuple[ActFn, float]] | None = None
    reward: Callable[[Any], RewardFn] | None = None
    role: Role = "driver"
    parse: Callable[[dict[str, Any], Path], Any] | None = None

    def learned(self, data: dict[str, Any], path: Path) -> Any:
        """The learned object of a file already read (``data``, its JSON object)."""
        return self.parse(data, path) if self.parse is not None else self.load(path)


class FormatRegistryError(RegistryError, ValueError):
    """A driver format refused: a bad family or role, registered twice, or unknown."""


def _check_format(family: str, fmt: DriverFormat) -> None:
    if not fmt.family or "/" in fmt.family or fmt.family != family:
        raise FormatRegistryError(f"driver format family must be a non-empty name without '/' "
                                  f"(and the key it is registered under), got {fmt.family!r}")
    if fmt.role not in ("model", "driver"):
        raise FormatRegistryError(f"driver format {fmt.family!r}: role must be 'model' or 'driver', got {fmt.role!r}")


#: The registered formats by family, in registration order (:func:`register_format`); the built-in
#: ones are ``"module:attr"`` entries, imported when first read.
FORMATS: Registry[DriverFormat] = Registry("driver format", error=FormatRegistryError, check=_check_format)
FORMATS.register("merge-irl-model", "sim.drivers.learned:MODEL_DRIVER_FORMAT")
FORMATS.register("merge-irl-cf-logit", "sim.drivers.learned:CF_DRIVER_FORMAT")
FORMATS.register("merge-irl-planner", "sim.drivers.planning:PLANNER_DRIVER_FORMAT")


_SCANNED: list[bool] = []


def _import_driver_modules() -> bool:
    """Import every module of ``sim.drivers`` not imported yet, once per process, so a driver type
    whose module calls :func:`register_format` needs no entry here; True the first time."""
    if _SCANNED:
        return False
    _SCANNED.append(True)
    import importlib
    import pkgutil

    import sim.drivers as package

    for info in pkgutil.iter_modules(package.__path__, package.__name__ + "."):
        importlib.import_module(info.name)
    return True


def register_format(fmt: DriverFormat) -> DriverFormat:
    """Add ``fmt`` to :data:`FORMATS`; returns it.

    Raises:
        ValueError (FormatRegistryError): a family with ``/`` or empty, an unknown role, or a family
            registered already.
    """
    FORMATS.register(fmt.family, fmt)
    return fmt


def unregister_format(family: str) -> None:
    """Remove a registered format (tests and plug-ins that register their own); no error if absent."""
    FORMATS.unregister(family)


def family_of(format_field: str) -> str:
    """The family of a ``format`` field: ``"merge-irl-planner/1"`` -> ``"merge-irl-planner"``."""
    return format_field.partition("/")[0]


def _known() -> str:
    return ", ".join(f"{f.family}/... ({f.label})" for f in FORMATS.values())


def _read(path: str | os.PathLike) -> tuple[str, dict[str, Any]]:
    """The ``format`` field and the JSON object of a learned file (the one read of the file).

    Raises:
        ModelFileError: a missing or unreadable file, not a JSON object, or no string ``format``.
    """
    data = read_json(path, what="model or driver file", error=ModelFileError)
    fmt = data.get("format") if isinstance(data, dict) else None
    if not isinstance(fmt, str):
        raise ModelFileError(f"{path}: not a model or driver file (no string 'format' field); expected one of: "
                             f"{_known()}")
    return fmt, data


def format_field(path: str | os.PathLike) -> str:
    """The ``format`` field of a learned file (JSON).

    Raises:
        ModelFileError: a missing or unreadable file, not a JSON object, or no string ``format``.
    """
    return _read(path)[0]


def format_of(path: str | os.PathLike, role: Role | None = None, *, option: str = "") -> DriverFormat:
    """The registered format of a learned file, checked against the ``role`` it is given as.

    Args:
        path: the file.
        role: ``"driver"`` or ``"model"``: refuse a file of the other role, naming the option it
            belongs to; None: any role.
        option: the option the file came with, for the message (``"--driver"``).

    Raises:
        ModelFileError: unreadable, no ``format``, an unregistered family (the known ones listed),
            or a file of the other role.
    """
    return _format_and_data(path, role, option=option)[0]


def _format_and_data(path: str | os.PathLike, role: Role | None = None, *,
                     option: str = "") -> tuple[DriverFormat, dict[str, Any]]:
    """:func:`format_of`, with the file's JSON object (read once, for :meth:`DriverFormat.learned`)."""
    fmt, data = _read(path)
    return _registered(path, fmt, role, option), data


def _registered(path: str | os.PathLike, fmt: str, role: Role | None, option: str) -> DriverFormat:
    """The registered format of the ``format`` field ``fmt``, checked against ``role``."""
    f = FORMATS.get(family_of(fmt))
    if f is None and _import_driver_modules():
        f = FORMATS.get(family_of(fmt))
    if f is None:
        raise ModelFileError(f"{path}: format {fmt!r} is not a registered model or driver format; expected one of: "
                             f"{_known()}")
    if role is not None and f.role != role:
        given = f" ({option})" if option else ""
        raise ModelFileError(f"{path}{given}: format {fmt!r} is not a {role}'s: it is a {f.label}; give it to "
                             "'merge-irl evaluate --driver'")
    return f


def check_role(path: str | os.PathLike, role: Role, *, option: str = "") -> None:
    """Refuse a file of a registered format of the other role (a driver given as a model, or the
    reverse), naming the option that takes it; anything else (no ``format`` field, an unknown
    one, an unreadable file) is left to the loader, which names its own fault.

    Raises:
        ModelFileError: a registered format of the other role.
    """
    try:
        data = _read(path)[1]
    except ModelFileError:
        return
    check_role_of(data, path, role, option=option)


def check_role_of(data: Any, path: str | os.PathLike, role: Role, *, option: str = "") -> None:
    """:func:`check_role` of a file already read: its parsed JSON ``data`` (any value)."""
    fmt = data.get("format") if isinstance(data, dict) else None
    if isinstance(fmt, str) and family_of(fmt) in FORMATS:
        _registered(path, fmt, role, option)


def load_driver(path: str | os.PathLike, role: Role | None = "driver") -> Any:
    """The learned object of a file, by its registered format (a ``PlanningDriver``, a
    ``CarFollowingLogit``, a ``SavedModel``, or a registered format's own).

    Raises:
        ModelFileError: see :func:`format_of`, and the format's own loader's errors.
    """
    f, data = _format_and_data(path, role)
    return f.learned(data, Path(path))


def driver_policy(path: str | os.PathLike, name: str = "", *, role: Role | None = "driver",
                  option: str = "") -> Policy:
    """The closed-loop policy of a learned file, named ``name`` or the file's stem.

    Raises:
        ModelFileError: see :func:`format_of`.
        PolicyError: the format's policy refuses the file's content (prefixed with the file).
    """
    from sim.drivers.policy import PolicyError

    f, data = _format_and_data(path, role, option=option)
    learned = f.learned(data, Path(path))
    try:
        return f.policy(learned, name or Path(path).stem, str(path))
    except PolicyError as e:
        raise type(e)(f"{path}: {e}") from None


def replay_act(path: str | os.PathLike) -> tuple[ActFn, float]:
    """``(act, decision_step_s)`` of a driver file for replaying real car-following pairs.

    Raises:
        ModelFileError: see :func:`format_of`, or a format that does not replay pairs.
    """
    f, data = _format_and_data(path, "driver", option="--driver")
    if f.replay_act is None:
        raise ModelFileError(f"{path}: a {f.label} does not replay car-following pairs")
    return f.replay_act(f.learned(data, Path(path)))


class UnreliableRewardWarning(UserWarning):
    """A learned file whose fit did not converge, or whose weights are unbounded, was taken as a
    reward (:func:`driver_reward`)."""


def driver_reward(path: str | os.PathLike) -> RewardFn:
    """The environment's reward of a learned file (any role).

    Warns:
        UnreliableRewardWarning: the file's fit did not converge (``converged`` false) or its
            weights are unbounded (``unbounded`` true): its reward is that of a point the
            optimiser stopped at, not of an optimum (:class:`irl.result.SavedModel`,
            ``PlanningDriver``).

    Raises:
        FileNotFoundError: no such file.
        ModelFileError: see :func:`format_of`, or a format without a reward (named).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"reward model file not found: {p}")
    f, data = _format_and_data(p)
    if f.reward is None:
        with_reward = ", ".join(x.label for x in FORMATS.values() if x.reward is not None)
        raise ModelFileError(f"{p}: a {f.label} has no reward; the environment's rewards come from: {with_reward}")
    learned = f.learned(data, p)
    why = [w for w, bad in (("its fit did not converge", not getattr(learned, "converged", True)),
                            ("its weights are unbounded (no finite maximiser: they diverged)",
                             bool(getattr(learned, "unbounded", False)))) if bad]
    if why:
        warnings.warn(f"{p}: taken as a reward although {' and '.join(why)}; its reward is that of where the "
                      "optimiser stopped, not of an optimum (refit, e.g. with l2 > 0)", UnreliableRewardWarning,
                      stacklevel=2)
    return f.reward(learned)


def policy_callable(path: str | os.PathLike, *, mode: bool = True, seed: int = 0) -> PolicyCallable:
    """Any learned file as a policy callable ``obs -> int`` (the action index 0..4) for the
    Gymnasium environment or a loop of one's own (:class:`sim.drivers.callables.PolicyCallable`;
    ``obs``: the ``[7]`` policy observation, :data:`sim.drivers.observe.CONTINUOUS_NAMES`).
    ``mode``: the most likely action (default), else sampled with
    ``numpy.random.default_rng(seed)``, for a driver without a fitted decision rule; a driver with
    one (the planning driver's most likely acceleration) decides by it either way, as it drives
    in the closed loop (:func:`sim.drivers.policy.fitted_decision`); call ``reset()`` at the start
    of each episode.

    Raises:
        ModelFileError: see :func:`format_of`.
        PolicyError: a file whose content its format's policy refuses.
    """
    from sim.drivers.callables import PolicyCallable

    return PolicyCallable(driver_policy(path, role=None), mode=mode, seed=seed)
