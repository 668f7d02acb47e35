"""``module:callable[:name]`` specs of callable drivers (``merge-irl evaluate --policy``):
:func:`parse_spec` checks one, :func:`load_callable` imports its callable (a dotted module or a
path to a ``.py`` file). The adapters themselves are :mod:`sim.drivers.callables.adapters`."""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.drivers.callables.messages import one_line
from sim.drivers.policy import PolicyError


@dataclass(frozen=True)
class CallableSpec:
    """A parsed ``module:callable[:name]`` spec.

    Attributes:
        module: a dotted module name, or a path to a ``.py`` file (made absolute).
        attr: the callable's name in the module (dotted for an attribute of an attribute).
        name: the policy's name (default: the callable's last name).
        is_file: ``module`` is a file path.
    """

    module: str
    attr: str
    name: str
    is_file: bool

    @property
    def text(self) -> str:
        """The spec again (``module:attr:name``; the file path absolute)."""
        return f"{self.module}:{self.attr}:{self.name}"


#: What a spec's name may hold: a file name (``rerun/<name>.rrd``), a report row and a ``--fail-if`` prefix.
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


def parse_spec(spec: str) -> CallableSpec:
    """Parse ``module:callable[:name]`` (module: a dotted name, or a path ending in ``.py`` or
    containing a path separator, e.g. ``./rules.py:cth`` or ``mypkg.rules:cth:cth-1.5s``).

    Raises:
        PolicyError: not two or three non-empty parts, a bad dotted name, a name with other
            characters than letters, digits, ``_``, ``-`` and ``.``, or a file path that is no file.
    """
    parts = str(spec).split(":")
    if len(parts) not in (2, 3) or not all(p.strip() for p in parts):
        raise PolicyError(f"--policy {spec!r}: expected module:callable[:name] (module: a dotted module name or a "
                          "path to a .py file)")
    module, attr = parts[0].strip(), parts[1].strip()
    name = parts[2].strip() if len(parts) == 3 else attr.rsplit(".", 1)[-1]
    if not all(s.isidentifier() for s in attr.split(".")):
        raise PolicyError(f"--policy {spec!r}: {attr!r} is not a Python name")
    if not _NAME.fullmatch(name) or name.endswith("."):
        raise PolicyError(f"--policy {spec!r}: the name {name!r} must be letters, digits, '_', '-' and '.' "
                          "(it names the report's row, the recording's file and --fail-if's POLICY.)")
    is_file = module.endswith(".py") or "/" in module or "\\" in module
    if is_file:
        path = Path(module).expanduser()
        if not path.is_file():
            raise PolicyError(f"--policy {spec!r}: no such file {module}")
        module = str(path.resolve())
    elif not all(s.isidentifier() for s in module.split(".")):
        raise PolicyError(f"--policy {spec!r}: {module!r} is neither a dotted module name nor a .py file")
    return CallableSpec(module, attr, name, is_file)


def _import(spec: CallableSpec, where: str) -> Any:
    if spec.is_file:
        path = Path(spec.module)
        digest = hashlib.sha256(str(path).encode()).hexdigest()[:10]
        mod_name = f"_merge_irl_policy_{path.stem if path.stem.isidentifier() else 'file'}_{digest}"
        if mod_name in sys.modules:
            return sys.modules[mod_name]
        ispec = importlib.util.spec_from_file_location(mod_name, path)
        if ispec is None or ispec.loader is None:
            raise PolicyError(f"{where}: cannot import {path} as a Python module")
        module = importlib.util.module_from_spec(ispec)
        sys.modules[mod_name] = module  # before running it: dataclasses and pickle look it up
        try:
            ispec.loader.exec_module(module)
        except Exception as e:  # the user's module may raise anything
            sys.modules.pop(mod_name, None)
            raise PolicyError(f"{where}: importing {path} failed ({type(e).__name__}: {one_line(e)})") from None
        return module
    try:
        return importlib.import_module(spec.module)
    except ModuleNotFoundError as e:
        raise PolicyError(f"{where}: no module {e.name!r} (a dotted module must be importable: installed or on "
                          "PYTHONPATH; or give a path to a .py file)") from None
    except Exception as e:
        raise PolicyError(f"{where}: importing {spec.module} failed ({type(e).__name__}: {one_line(e)})") from None


def load_callable(spec: str | CallableSpec) -> tuple[Callable[[np.ndarray], Any], CallableSpec]:
    """The callable of a ``module:callable[:name]`` spec (:func:`parse_spec`) and the parsed spec.

    A ``.py`` file is imported under a name of its own (the same file: the same module, once per
    process).

    Raises:
        PolicyError: a bad spec, a missing file or module, an import that fails, a missing
            attribute, or an attribute that is neither callable nor has a ``predict`` method.
    """
    s = parse_spec(spec) if isinstance(spec, str) else spec
    where = f"--policy {s.module}:{s.attr}"
    obj: Any = _import(s, where)
    for part in s.attr.split("."):
        if not hasattr(obj, part):
            raise PolicyError(f"{where}: {s.module} has no attribute {s.attr!r}")
        obj = getattr(obj, part)
    if not callable(obj) and not callable(getattr(obj, "predict", None)):
        raise PolicyError(f"{where}: {s.attr} is a {type(obj).__name__}, not callable (give a function "
                          "obs -> action, or an object with predict(obs, deterministic=True))")
    return obj, s
