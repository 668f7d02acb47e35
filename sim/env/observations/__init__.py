"""The environments' observations, chosen by name: ``observation="policy"`` (the default).

An observation is an object with ``space() -> gymnasium.spaces.Space`` and ``observe(obs) ->
numpy array`` of A's :class:`~sim.drivers.observe.MergeObservation` at a decision
(:class:`Observation`), made from the environment's :class:`~sim.env.config.MergeEnvConfig`
(``factory(config) -> Observation``; a class taking the config is one). Adding one is one file,
in any of three ways:

* a module ``sim/env/observations/<name>.py`` that calls ``register_observation("<name>", Cls)``:
  found by name in this folder and imported the first time it is asked for (nothing else lists it);
* a module of your own, anywhere importable: ``observation="my_module:MyObservation"``;
* ``register_observation(name, Cls)`` in your own code, then ``observation=name``.

The built-in: ``"policy"`` (:mod:`sim.env.observations.policy`), the 7 columns a policy sees.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np
from gymnasium import spaces

from merge_irl.registry import Registry, RegistryError, resolve_ref
from sim.drivers.observe import MergeObservation

__all__ = ["DEFAULT_OBSERVATION", "OBSERVATIONS", "Observation", "ObservationFactory", "make_observation",
           "observation_factory", "observation_names", "register_observation"]

#: The name of the environments' default observation.
DEFAULT_OBSERVATION = "policy"


@runtime_checkable
class Observation(Protocol):
    """What the agent sees at a decision: ``space()`` (constant for one environment) and
    ``observe(obs)``, an array in that space (a new array each call)."""

    def space(self) -> spaces.Space[Any]: ...

    def observe(self, obs: MergeObservation) -> np.ndarray: ...


#: Makes an :class:`Observation` for an environment of a config (a class taking the config; typed
#: ``Any`` here since :mod:`sim.env.config` imports this module).
ObservationFactory = Callable[[Any], Observation]

#: The observations registered so far (the modules of this folder register when first asked for).
OBSERVATIONS: Registry[ObservationFactory] = Registry("observation")


def register_observation(name: str, factory: ObservationFactory, *, replace: bool = False) -> ObservationFactory:
    """Make ``factory`` (a class taking a :class:`~sim.env.config.MergeEnvConfig`) selectable as
    ``observation=name``; returns it (usable as a class decorator's body).

    Raises:
        TypeError: ``factory`` not callable.
        merge_irl.registry.RegistryError: an empty name, or one registered already (not ``replace``).
    """
    if not callable(factory):
        raise TypeError(f"register_observation({name!r}, ...): an observation must be a class or callable "
                        f"taking the environment's config, got {type(factory).__name__}")
    OBSERVATIONS.register(name, factory, replace=replace)
    return factory


def _folder_modules() -> list[str]:
    return [m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_")]


def observation_names() -> tuple[str, ...]:
    """Every name ``observation=`` takes: the registered ones, then this folder's modules."""
    names = list(OBSERVATIONS.names())
    return tuple(names + [m for m in _folder_modules() if m not in names])


def observation_factory(name: str) -> ObservationFactory:
    """The factory of ``name``: a registered name, a module of this folder (imported, and it
    registers itself), or ``"module:attr"``.

    Raises:
        merge_irl.registry.RegistryError: an unknown name (the names listed), a ``"module:attr"``
            that does not import, or a module of this folder that registers no such name.
    """
    if name in OBSERVATIONS:
        return OBSERVATIONS[name]
    if ":" in name:
        factory = resolve_ref(name)
        if not callable(factory):
            raise RegistryError(f"observation {name!r} is a {type(factory).__name__}, not a class or callable")
        return factory
    if name in _folder_modules():
        importlib.import_module(f"{__name__}.{name}")
        if name not in OBSERVATIONS:
            raise RegistryError(f"observation module {__name__}.{name} registered no observation {name!r} "
                                f"(call register_observation({name!r}, ...) in it)")
        return OBSERVATIONS[name]
    raise RegistryError(f"unknown observation {name!r}; known: {', '.join(observation_names())} "
                        "(or 'module:Class' of your own)")


def make_observation(config: Any) -> Observation:
    """The :class:`Observation` of ``config.observation`` (a name or a factory) for ``config`` (a
    :class:`~sim.env.config.MergeEnvConfig`).

    Raises:
        merge_irl.registry.RegistryError: an unknown name (:func:`observation_factory`).
        TypeError: the factory made no :class:`Observation` (``space`` and ``observe`` missing).
    """
    spec = config.observation
    factory = observation_factory(spec) if isinstance(spec, str) else spec
    made = factory(config)
    if not isinstance(made, Observation):
        raise TypeError(f"observation {spec!r} made a {type(made).__name__}, which has no space() and observe(obs)")
    return made
