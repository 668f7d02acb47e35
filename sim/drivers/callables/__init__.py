"""Callable drivers: any callable ``obs -> action`` as a closed-loop driver, and any driver as such
a callable.

* :mod:`~sim.drivers.callables.adapters`: the two adapters, named by their direction:
  :class:`DriverFromCallable` (a user's callable as a driver; ``merge-irl evaluate --policy``) and
  :class:`CallableFromDriver` (a driver as a callable ``obs [7] -> action index``, e.g. for the
  Gymnasium environment). Their old names, ``CallablePolicy`` and ``PolicyCallable``, still work.
* :mod:`~sim.drivers.callables.actions`: what such a callable returns, checked
  (:func:`parse_action`), and how it is asked (:func:`act_of`).
* :mod:`~sim.drivers.callables.specs`: ``module:callable[:name]`` specs (:func:`parse_spec`,
  :func:`load_callable`).
* :mod:`~sim.drivers.callables.limits`: a callable asked with a time limit
  (:func:`call_with_limit`, :class:`DecisionTimeout`).
* :mod:`~sim.drivers.callables.messages`: the one-line text of a callable's error
  (:func:`~sim.drivers.callables.messages.one_line`).

This package is the declared facade of these names (``from sim.drivers.callables import
DriverFromCallable``).
"""

from sim.drivers.callables.actions import PLAUSIBLE_ACC_MPS2, act_of, parse_action
from sim.drivers.callables.adapters import (
    TRUCK_MIN_LENGTH_FT,
    CallableFromDriver,
    CallablePolicy,
    DriverFromCallable,
    PolicyCallable,
)
from sim.drivers.callables.limits import DEFAULT_DECISION_LIMIT_S, DecisionTimeout, call_with_limit, check_limit
from sim.drivers.callables.specs import CallableSpec, load_callable, parse_spec

__all__ = ["DEFAULT_DECISION_LIMIT_S", "PLAUSIBLE_ACC_MPS2", "TRUCK_MIN_LENGTH_FT", "CallableFromDriver",
           "CallablePolicy", "CallableSpec", "DecisionTimeout", "DriverFromCallable", "PolicyCallable", "act_of",
           "call_with_limit", "check_limit", "load_callable", "parse_action", "parse_spec"]
