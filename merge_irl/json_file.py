"""Reading a JSON (or TOML) file and validating it against a schema, with one-line errors.

Every file format the project reads is described by a schema (a pydantic model, next to the
dataclass it builds: :class:`irl.result.SavedModel`, the car-following logit, the planning
driver, the calibration params file); this module is the one place that reads such a file and
turns a schema's complaint into the loader's own error class, as one line naming the file and
the field path::

    model.json: settings.gamma: must be less than 1, got 1.5

:func:`read_json` reads and parses (no such file, unreadable, not JSON: one line each);
:func:`validate` checks parsed data against a schema; :func:`describe` is the message of a
:class:`pydantic.ValidationError`. The caller passes the error class (``ModelFileError``,
``SpecError``, ...), so each loader keeps raising what it raised before.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar, get_type_hints

from pydantic import BaseModel, ConfigDict, TypeAdapter, ValidationError, create_model

M = TypeVar("M", bound=BaseModel)
T = TypeVar("T")

#: The schemas' common settings: JSON types as written (no ``"1.5"`` for a number, no ``true``
#: for 1), unknown fields ignored (files carry provenance a reader need not know).
STRICT = ConfigDict(strict=True, extra="ignore")


def read_json(path: str | os.PathLike, *, what: str, error: type[Exception]) -> Any:
    """The parsed JSON of the UTF-8 file ``path``.

    Args:
        what: what the file is, for messages (``"model file"``).
        error: the exception class raised (one argument, the message).

    Raises:
        error: ``"<path>: no such <what>"``, ``"<path>: cannot read <what> (...)"`` (a folder, no
            permission) or ``"<path>: not a JSON <what> (...)"`` (bad bytes, bad JSON, too deep).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{p}: no such {what}") from None
    except OSError as e:
        raise error(f"{p}: cannot read {what} ({e.strerror or e})") from None
    except UnicodeDecodeError as e:
        raise error(f"{p}: not a JSON {what} (not UTF-8 text: byte {e.start})") from None
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as e:  # JSONDecodeError is a ValueError
        raise error(f"{p}: not a JSON {what} ({type(e).__name__}: {str(e)[:200]})") from None


def read_json_object(path: str | os.PathLike, *, what: str, error: type[Exception]) -> dict[str, Any]:
    """:func:`read_json`, which must be a JSON object.

    Raises:
        error: as :func:`read_json`, or a top level that is not an object.
    """
    data = read_json(path, what=what, error=error)
    if not isinstance(data, dict):
        raise error(f"{Path(path)}: expected a JSON object at top level, got {json_type(data)}")
    return data


def validate(schema: type[M], data: Any, source: str | os.PathLike, *, error: type[Exception], at: str = "",
             context: dict[str, Any] | None = None) -> M:
    """``data`` validated by the pydantic model ``schema``.

    Args:
        source: the file (or ``"<dict>"``), first in messages.
        error: the exception class raised.
        at: where ``data`` sits in its file (``"drivers.car[0]"``), before each field path.
        context: passed to the schema's validators (pydantic's validation context).

    Raises:
        error: ``"<source>: <field.path>: <problem>"`` (:func:`describe`).
    """
    try:
        return schema.model_validate(data, context=context)
    except ValidationError as e:
        raise error(f"{source}: {describe(e, at=at)}") from None


def validate_as(adapter: TypeAdapter[Any], data: Any, source: str | os.PathLike, *,
                error: type[Exception]) -> Any:
    """As :func:`validate`, with a :class:`pydantic.TypeAdapter` (e.g. over a dataclass)."""
    try:
        return adapter.validate_python(data)
    except ValidationError as e:
        raise error(f"{source}: {describe(e)}") from None


def dataclass_schema(cls: type, *, optional: Mapping[str, Any] | None = None) -> type[BaseModel]:
    """A strict pydantic model of the dataclass ``cls``'s fields, typed by its annotations, no
    other keys allowed: the dataclass stays the public type (``cls(**model.model_dump())``, whose
    own checks then run); the schema checks the JSON types and names the field at fault.

    Args:
        optional: the fields a file may leave out, with the values they then take (None: every
            field, with the dataclass's defaults; ``{}``: every field required).
    """
    hints = get_type_hints(cls)
    specs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if optional is None and f.default is not dataclasses.MISSING:
            specs[f.name] = (hints[f.name], f.default)
        elif optional is not None and f.name in optional:
            specs[f.name] = (hints[f.name], optional[f.name])
        else:
            specs[f.name] = (hints[f.name], ...)
    return create_model(f"{cls.__name__}Schema", __config__=ConfigDict(strict=True, extra="forbid"), **specs)


def to_dataclass(cls: type[T], model: Any) -> T:
    """The dataclass ``cls`` of a :func:`dataclass_schema` model's values (its own checks run:
    they raise what they raise)."""
    return cls(**dict(model))


def field_path(loc: Sequence[int | str]) -> str:
    """A pydantic error location as a field path: ``("settings", "gamma")`` -> ``settings.gamma``,
    ``("theta", 3)`` -> ``theta[3]`` (``<top>`` when empty)."""
    out = ""
    for part in loc:
        if part == "[key]":  # pydantic's mark of an error in a mapping's key (the key precedes it)
            continue
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out or "<top>"


_PHRASES = (("Input should be ", "must be "), ("Value error, ", ""), ("Assertion failed, ", ""),
            ("Field required", "missing"), ("Extra inputs are not permitted", "unknown field"),
            ("List should have", "must have"), ("Dictionary should have", "must have"),
            (" after validation", ""), ("a valid boolean", "true or false"), ("a valid number", "a number"),
            ("a valid integer", "an integer"), ("a valid list", "a list"), ("a valid dictionary", "an object"),
            ("a valid string", "a string"))


def describe(e: ValidationError, *, at: str = "") -> str:
    """One line for a validation error: its first problem as ``field.path: problem, got value``
    (``(and N more)`` when there are more; a validator's own message as it says it; a check of
    the whole object, with no field path, its message alone)."""
    errors = e.errors(include_url=False)
    first = errors[0]
    msg = str(first["msg"])
    for old, new in _PHRASES:
        msg = msg.replace(old, new)
    msg = re.sub(r" or instance of \w+", "", msg)  # a nested schema's class name says nothing to users
    if first["type"] not in ("missing", "extra_forbidden", "value_error") and "input" in first:
        msg += f", got {brief(first['input'])}"
    more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
    if not first["loc"] and not at:  # a check across fields says where itself
        return f"{msg}{more}"
    where = field_path(first["loc"])
    if at:
        where = at if where == "<top>" else at + ("" if where.startswith("[") else ".") + where
    return f"{where}: {msg}{more}"


def json_type(value: Any) -> str:
    """The JSON type of ``value`` in words (``"an object"``, ``"a list"``, ``"null"``, ...)."""
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number", type(None): "null"}.get(type(value), type(value).__name__)


def brief(value: Any) -> str:
    """``repr(value)``, cut to about 60 characters for messages."""
    text = repr(value)
    return text if len(text) <= 60 else text[:50] + "..."
