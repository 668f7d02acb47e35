"""A user's callable asked with a time limit: :func:`call_with_limit`.

A callable driver (``merge-irl evaluate --policy``) is code the evaluation does not control: one
that blocks (a lock, a network call, an endless loop) would hold its episode, and the whole
evaluation, forever. Each decision is therefore given at most ``limit_s`` seconds
(:data:`DEFAULT_DECISION_LIMIT_S` unless told otherwise), after which it fails with a
:class:`DecisionTimeout` naming the policy and the option that sets the limit.

How the callable is stopped depends on where it runs:

* in a process's main thread (the process-pool workers, ``serial``): a ``SIGALRM`` timer
  interrupts the callable itself (a sleep, a lock's wait, a Python loop), so nothing of it stays
  behind. A callable stuck inside C code that never returns to Python is interrupted only when it
  does; the process-pool workers are ended with the evaluation in any case.
* in another thread (a Dask worker's task thread), or where ``SIGALRM`` is already in use: the
  callable runs in a daemon thread that is waited for at most ``limit_s``; a callable that overruns
  is abandoned there (it cannot be stopped from outside) and ends with its worker process.
"""

from __future__ import annotations

import math
import signal
import threading
from collections.abc import Callable
from typing import Any

from sim.drivers.policy import PolicyError

#: Seconds one decision of a callable driver may take by default: a policy network answers in
#: milliseconds, a first call that loads weights in a few seconds; a minute is no honest policy.
DEFAULT_DECISION_LIMIT_S = 60.0


class DecisionTimeout(PolicyError):
    """A callable driver gave no action within its time limit (``retry = False``, and ``abort =
    True``: a sweep stops at the first one instead of waiting out every other episode)."""

    abort = True


class _Alarm(BaseException):
    """Raised inside the callable by the timer: a BaseException, so that the callable's own
    ``except Exception`` does not swallow it."""


def check_limit(limit_s: float, *, option: str = "--policy-timeout") -> float:
    """``limit_s`` as a float.

    Raises:
        PolicyError: not a positive finite number of seconds (``option`` named).
    """
    try:
        v = float(limit_s)
    except (TypeError, ValueError):
        raise PolicyError(f"{option} {limit_s!r}: expected a positive number of seconds") from None
    if not (v > 0 and math.isfinite(v)):
        raise PolicyError(f"{option} {limit_s!r}: expected a positive finite number of seconds")
    return v


def call_with_limit(fn: Callable[[Any], Any], arg: Any, limit_s: float, *, where: str,
                    option: str = "--policy-timeout") -> Any:
    """``fn(arg)``, given at most ``limit_s`` seconds (see the module docstring for how).

    Args:
        fn: the callable (its own exceptions pass through unchanged).
        arg: its one argument.
        limit_s: seconds (> 0).
        where: the policy, as errors name it (``policy 'x' (spec)``).
        option: the option that sets the limit, named in the error.

    Raises:
        DecisionTimeout: no answer within ``limit_s``.
    """
    if threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer") \
            and signal.getsignal(signal.SIGALRM) in (signal.SIG_DFL, signal.SIG_IGN, None):
        return _call_with_alarm(fn, arg, limit_s, where=where, option=option)
    return _call_in_thread(fn, arg, limit_s, where=where, option=option)


def _timeout(limit_s: float, where: str, option: str) -> DecisionTimeout:
    return DecisionTimeout(f"{where}: no action within {limit_s:g} s at one decision (a callable that blocks: a "
                           f"lock, a network call, an endless loop?); a slower honest policy can be given more with "
                           f"{option} SECONDS")


def _call_with_alarm(fn: Callable[[Any], Any], arg: Any, limit_s: float, *, where: str, option: str) -> Any:
    def on_alarm(signum, frame):
        raise _Alarm()

    previous = signal.signal(signal.SIGALRM, on_alarm)
    try:
        signal.setitimer(signal.ITIMER_REAL, limit_s)
        try:
            return fn(arg)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
    except _Alarm:
        raise _timeout(limit_s, where, option) from None
    finally:
        signal.signal(signal.SIGALRM, previous)


def _call_in_thread(fn: Callable[[Any], Any], arg: Any, limit_s: float, *, where: str, option: str) -> Any:
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["out"] = fn(arg)
        except BaseException as e:  # noqa: BLE001 - handed to the caller as it was raised
            box["err"] = e

    t = threading.Thread(target=target, name="merge-irl-policy-call", daemon=True)
    t.start()
    t.join(limit_s)
    if t.is_alive():
        raise _timeout(limit_s, where, option)
    if "err" in box:
        raise box["err"]
    return box["out"]
