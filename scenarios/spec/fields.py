"""Reading one field of a scenario spec: type, magnitude and range checks that raise
:class:`scenarios.errors.SpecError` as ``file: field.path: problem`` (used by
:mod:`scenarios.spec.parse`, which knows the file layout).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar

from scenarios.errors import SpecError

T = TypeVar("T")

#: No field of a scenario is meaningful beyond this (seconds, metres, veh/h).
MAX_MAGNITUDE = 1e15


class FieldContext:
    """Builds error messages of the form ``file: field.path: problem``."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, path: str, msg: str) -> SpecError:
        """The error (to raise) for the field at ``path``."""
        return SpecError(f"{self.source}: {path}: {msg}")


def check_keys(ctx: FieldContext, path: str, data: Any, allowed: list[str]) -> dict[str, Any]:
    """``data`` itself, once it is a table whose keys are all in ``allowed``.

    Raises:
        SpecError: not a table, or an unknown key (named with its path).
    """
    if not isinstance(data, dict):
        raise ctx.fail(path or "<top>", f"must be a table, got {type(data).__name__}")
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        where = f"{path}.{unknown[0]}" if path else unknown[0]
        raise ctx.fail(where, f"unknown key (expected one of: {', '.join(allowed)})")
    return data


def number_value(v: Any, *, integer: bool = False) -> float | int:
    """``v`` as a float (or an int with ``integer``); booleans are not numbers.

    Raises:
        ValueError: not a number (an integer), above :data:`MAX_MAGNITUDE` in magnitude, or not
            finite (the message says which; the caller names the field).
    """
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        kind = "an integer" if integer else "a number"
        raise ValueError(f"must be {kind}, got {v!r} ({type(v).__name__})")
    if abs(v) > MAX_MAGNITUDE:  # also keeps huge TOML integers from overflowing float()
        raise ValueError(f"must be at most {MAX_MAGNITUDE:g} in magnitude, got {short_repr(v)}")
    if not integer and not math.isfinite(v):
        raise ValueError(f"must be finite, got {v!r}")
    return int(v) if integer else float(v)


def positive_value(v: Any, *, integer: bool = False) -> float | int:
    """:func:`number_value`, above 0 (ValueError otherwise)."""
    x = number_value(v, integer=integer)
    if x <= 0:
        raise ValueError(f"must be positive, got {v!r}")
    return x


def non_negative_value(v: Any) -> float:
    """:func:`number_value`, at least 0 (ValueError otherwise)."""
    x = number_value(v)
    if x < 0:
        raise ValueError(f"must be >= 0, got {v!r}")
    return x


def string_value(v: Any, choices: tuple[str, ...] | None = None) -> str:
    """``v``, a string (one of ``choices`` when given); ValueError otherwise."""
    if not isinstance(v, str):
        raise ValueError(f"must be a string, got {v!r} ({type(v).__name__})")
    if choices is not None and v not in choices:
        raise ValueError(f"must be one of {', '.join(choices)}, got {v!r}")
    return v


def _at(ctx: FieldContext, path: str, check: Callable[..., T], *args: Any, **kw: Any) -> T:
    try:
        return check(*args, **kw)
    except ValueError as e:
        raise ctx.fail(path, str(e)) from None


def number(ctx: FieldContext, path: str, v: Any, *, integer: bool = False) -> float | int:
    """:func:`number_value` of the field at ``path``.

    Raises:
        SpecError: not a number (an integer), above :data:`MAX_MAGNITUDE` in magnitude, or not finite.
    """
    return _at(ctx, path, number_value, v, integer=integer)


def is_float(text: str) -> bool:
    """Whether ``float(text)`` parses."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def short_repr(v: Any) -> str:
    """``repr(v)``, cut to about 40 characters for error messages."""
    text = repr(v)
    return text if len(text) <= 40 else text[:20] + "..." + text[-8:]


def positive(ctx: FieldContext, path: str, v: Any, *, integer: bool = False) -> float | int:
    """:func:`number`, above 0.

    Raises:
        SpecError: as :func:`number`, or not above 0.
    """
    return _at(ctx, path, positive_value, v, integer=integer)


def non_negative(ctx: FieldContext, path: str, v: Any) -> float:
    """:func:`number`, at least 0.

    Raises:
        SpecError: as :func:`number`, or below 0.
    """
    return _at(ctx, path, non_negative_value, v)


def string(ctx: FieldContext, path: str, v: Any, choices: tuple[str, ...] | None = None) -> str:
    """``v``, a string (one of ``choices`` when given).

    Raises:
        SpecError: not a string, or not one of ``choices``.
    """
    return _at(ctx, path, string_value, v, choices)
