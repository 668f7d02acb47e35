"""The IRL method registry: the one list of methods, with everything the rest of the code reads
about a method (its label, its order in the paper's tables, its cost, what it needs from a
problem and the options it takes).

:func:`irl.fit.fit` dispatches on it, model files are checked against it (:mod:`irl.result`),
``merge-irl learn``, ``merge-irl reproduce`` and the reports list and label methods from it.
Adding a method is a module with its ``fit_x`` function and one :func:`register` call (below, or
from your own code). Fitters and option builders are named as ``"module:function"`` strings and
imported when first used, so reading the registry imports no solver.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from irl.errors import ConfigError
from merge_irl.registry import Registry, RegistryError, resolve_ref

#: A fitter or option builder: a callable, or ``"module:function"`` imported on first use.
Ref = str | Callable[..., Any]


def resolve(ref: Ref) -> Callable[..., Any]:
    """The callable ``ref`` names (``"module:function"``), or ``ref`` itself.

    Raises:
        ConfigError: ``ref`` is a string that does not name an importable function.
    """
    return ref if callable(ref) else resolve_ref(ref, ConfigError)


@dataclass(frozen=True)
class Method:
    """One IRL method.

    Attributes:
        name: the key (``"qavg"``, ...), as saved in ``model.json``.
        label: the paper's name (``"Q-Avg"``, ...).
        fitter: ``fitter(demos, config, rng, *, theta0, progress, [transitions], **options) ->
            FitResult`` (a callable or ``"module:function"``).
        needs_transitions: the method takes the problem's ``[S, A, S]`` model (MLIRL needs one;
            REIRL uses it for its baseline and final log-likelihood; Q-Avg and Q-SM are model-free).
        options: the further keyword arguments the fitter accepts.
        problem_options: ``f(problem, config, **settings) -> dict`` of the options a fit on a
            :class:`~irl.problems.Problem` passes (e.g. REIRL's baseline and padding), or None.
        cost: relative cost of one trial (larger first when a sweep schedules trials).
    """

    name: str
    label: str
    fitter: Ref
    needs_transitions: bool = False
    options: tuple[str, ...] = ()
    problem_options: Ref | None = None
    cost: int = 0

    def fit_function(self) -> Callable[..., Any]:
        """The fitter, imported if named by a string."""
        return resolve(self.fitter)

    def options_for(self, problem: Any, config: Any, **settings: Any) -> dict[str, Any]:
        """The options a fit of this method on ``problem`` passes (``problem_options``)."""
        return {} if self.problem_options is None else dict(resolve(self.problem_options)(problem, config, **settings))


class MethodRegistryError(RegistryError, ConfigError):
    """An unknown IRL method, one registered twice or without a name (a :class:`ConfigError`)."""


#: The methods, in the row order of the paper's tables (MLIRL, Q-Avg, Q-SM, REIRL).
REGISTRY: Registry[Method] = Registry("IRL method", error=MethodRegistryError)


def register(method: Method, *, replace: bool = False) -> Method:
    """Add ``method`` to :data:`REGISTRY` (at the end of the order) and return it.

    Raises:
        MethodRegistryError (a ConfigError): a method of that name is registered and ``replace``
            is False, or the name is empty.
    """
    REGISTRY.register(method.name, method, replace=replace)
    return method


def unregister(name: str) -> None:
    """Remove ``name`` from :data:`REGISTRY` (nothing if absent)."""
    REGISTRY.unregister(name)


def method_names() -> tuple[str, ...]:
    """The registered method names, in registry order."""
    return REGISTRY.names()


def get_method(name: str) -> Method:
    """The registered method ``name``.

    Raises:
        MethodRegistryError (a ConfigError): no such method (the message lists the registered ones).
    """
    return REGISTRY[name]


register(Method("mlirl", "MLIRL", "irl.methods.mlirl:fit_mlirl", needs_transitions=True, cost=2))
register(Method("qavg", "Q-Avg", "irl.methods.qavg:fit_qavg", options=("fallback_next",),
                problem_options="irl.problems:model_free_options", cost=0))
register(Method("qsm", "Q-SM", "irl.methods.qsm:fit_qsm", options=("fallback_next",),
                problem_options="irl.problems:model_free_options", cost=3))
register(Method("reirl", "REIRL", "irl.methods.reirl:fit_reirl", needs_transitions=True,
                options=("baseline", "epsilon", "delta", "n_baseline", "pad_step", "theta_cap"),
                problem_options="irl.methods.reirl:problem_options", cost=1))
