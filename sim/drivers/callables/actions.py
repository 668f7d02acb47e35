"""What a callable driver returns, and how it is asked: :func:`parse_action` checks a returned
action (an action index ``0..4`` or A's acceleration in m/s^2, numpy scalars and one-element arrays
as their element) and :func:`act_of` calls a function or a ``predict(obs, deterministic=True)``
object alike. The adapters themselves are :mod:`sim.drivers.callables.adapters`."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from irl.domains.merge.actions import N_ACTIONS
from sim.drivers.policy import PolicyError

#: Accelerations (m/s^2) a continuous action may ask for: about 2 g of braking to 1 g of
#: acceleration, beyond any road vehicle; outside it is a bug (units), refused. Within it a
#: deceleration is still capped at A's emergency deceleration, as for every driver.
PLAUSIBLE_ACC_MPS2 = (-20.0, 10.0)


def parse_action(value: Any, *, where: str = "policy") -> int | float:
    """The action a callable returned: an ``int`` action index or a ``float`` acceleration (m/s^2).

    Accepts Python ints and floats, numpy scalars and one-element arrays (and anything
    ``numpy.asarray`` turns into one, e.g. a CPU tensor); integer dtypes are action indices, float
    dtypes accelerations.

    Raises:
        PolicyError: a bool, a tuple, an array of more than one element, another type, an index
            outside ``0..4``, or an acceleration that is not finite or outside
            :data:`PLAUSIBLE_ACC_MPS2` (``where`` names the policy).
    """
    x = value
    if isinstance(x, (bool, np.bool_)):
        raise PolicyError(f"{where}: returned a bool ({x!r}); expected an action index 0..{N_ACTIONS - 1} (int) "
                          "or A's acceleration in m/s^2 (float)")
    if isinstance(x, (tuple, list, dict, str, bytes)) or x is None:
        raise PolicyError(f"{where}: returned {type(x).__name__} {_short(x)}; expected an action index "
                          f"0..{N_ACTIONS - 1} (int) or A's acceleration in m/s^2 (float)"
                          + (" (a predict() result? give the object, whose predict is called)"
                             if isinstance(x, tuple) else ""))
    if not isinstance(x, (int, float, np.integer, np.floating)):
        if not (isinstance(x, np.ndarray) or hasattr(x, "__array__")):
            raise PolicyError(f"{where}: returned {type(x).__name__}; expected an action index 0..{N_ACTIONS - 1} "
                              "(int) or A's acceleration in m/s^2 (float)")
        a = np.asarray(x)
        if a.size != 1:
            raise PolicyError(f"{where}: returned an array of shape {a.shape}; expected one action")
        if a.dtype.kind not in "iuf":
            raise PolicyError(f"{where}: returned an array of dtype {a.dtype}; expected an integer action index "
                              "or a float acceleration (m/s^2)")
        x = a.reshape(()).item()
    if isinstance(x, (int, np.integer)):
        i = int(x)
        if not 0 <= i < N_ACTIONS:
            raise PolicyError(f"{where}: returned action {i}; an action index is 0..{N_ACTIONS - 1} "
                              "(High Brake, Low Brake, Zero, Low Accel, High Accel)")
        return i
    f = float(x)
    if not math.isfinite(f):
        raise PolicyError(f"{where}: returned acceleration {f}; expected a finite number (m/s^2)")
    lo, hi = PLAUSIBLE_ACC_MPS2
    if not lo <= f <= hi:
        raise PolicyError(f"{where}: returned acceleration {f:g} m/s^2, beyond any road vehicle's "
                          f"({lo:g} .. {hi:g} m/s^2; a unit mix-up, ft/s^2 or km/h/s?)")
    return f


def _short(x: Any) -> str:
    r = repr(x)
    return r if len(r) <= 60 else r[:57] + "..."


def act_of(fn: Callable[..., Any]) -> Callable[[np.ndarray], Any]:
    """The function that asks ``fn`` for an action on an observation: ``fn.predict(obs,
    deterministic=True)[0]`` when ``fn`` has a ``predict`` method (Stable-Baselines3, imitation),
    else ``fn(obs)``.

    Raises:
        PolicyError: ``fn`` is neither callable nor has a ``predict`` method.
    """
    predict = getattr(fn, "predict", None)
    if callable(predict):
        def via_predict(obs: np.ndarray) -> Any:
            out = predict(obs, deterministic=True)
            if not (isinstance(out, tuple) and len(out) == 2):
                raise PolicyError(f"{_label(fn)}.predict returned {type(out).__name__}; expected (action, state)")
            return out[0]
        return via_predict
    if not callable(fn):
        raise PolicyError(f"{_label(fn)} is not callable and has no predict() method")
    return fn


def _label(fn: Any) -> str:
    return getattr(fn, "__qualname__", None) or type(fn).__name__
