"""A small TOML writer for scenario specs (tables, arrays of tables, scalars, flat arrays)."""

from __future__ import annotations

import math
from typing import Any

_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b", "\f": "\\f"}


def _scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write non-finite float {v!r} to TOML")
        return repr(v)
    if isinstance(v, str):
        return '"' + "".join(_ESCAPES.get(c, c) if c in _ESCAPES or c.isprintable() or c == " "
                             else f"\\u{ord(c):04X}" if ord(c) <= 0xFFFF else f"\\U{ord(c):08X}"
                             for c in v) + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_scalar(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_scalar(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _emit(lines: list[str], prefix: str, table: dict[str, Any]) -> None:
    subtables = []
    for k, v in table.items():
        if isinstance(v, dict) and any(isinstance(x, (dict, list)) for x in v.values()) or (
            isinstance(v, dict) and prefix == "" ):
            subtables.append((k, v))
        elif _is_table_array(v):
            subtables.append((k, v))
        else:
            lines.append(f"{k} = {_scalar(v)}")
    for k, v in subtables:
        name = f"{prefix}.{k}" if prefix else k
        if _is_table_array(v):
            for item in v:
                lines.append("")
                lines.append(f"[[{name}]]")
                _emit(lines, name, item)
        else:
            lines.append("")
            lines.append(f"[{name}]")
            _emit(lines, name, v)


def dumps(data: dict[str, Any]) -> str:
    """TOML text for ``data`` (a mapping of str to scalars, lists, and nested mappings)."""
    lines: list[str] = []
    _emit(lines, "", data)
    return "\n".join(lines).lstrip("\n") + "\n"
