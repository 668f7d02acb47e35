"""The one registry type: named entries, in registration order, imported on first use.

Every list of things the code chooses among by name is a :class:`Registry`: the IRL methods
(:data:`irl.methods.registry.REGISTRY`), the IRL domains (:data:`irl.problems.DOMAINS`), the
tabular baselines (:data:`irl.baselines.BASELINE_FITTERS`), the driver formats
(:data:`sim.drivers.formats.FORMATS`, whose entries also carry each format's environment
reward), the evaluation's baseline drivers (:data:`sim.drivers.baselines.BASELINES`), the
site profiles (:data:`sim.runtime.sites.SITES`), the environments' named rewards
(:data:`sim.env.task_reward.TASK_REWARDS`) and observations (:data:`sim.env.observations.OBSERVATIONS`).

An entry is the object itself or a ``"module:attr"`` string, imported the first time the entry is
read (``registry[name]``, :meth:`Registry.values`, ...), so registering a built-in imports
nothing. A registry reads as a read-only mapping (``name in r``, ``r[name]``, ``r.get(name)``,
``list(r)``, ``r.items()``), in registration order; :meth:`Registry.register` and
:meth:`Registry.unregister` change it.

Errors: one class, :class:`RegistryError` (a :class:`KeyError` whose message is one line). A
registry that raised another class before names a subclass of both (``error=``), so old
``except`` clauses keep working.

Data and the standard library only: this module imports nothing of ours.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping
from typing import Any, Generic, TypeVar

T = TypeVar("T")

__all__ = ["Registry", "RegistryError", "resolve_ref"]


class RegistryError(KeyError):
    """An unknown name, a name registered twice, an invalid entry, or a ``"module:attr"`` entry that
    does not import. Its message is one line (not quoted as :class:`KeyError`'s are)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


def resolve_ref(ref: str, error: type[Exception] = RegistryError) -> Any:
    """The object ``"module:attr"`` names (``attr`` may be dotted: ``"m:Class.method"``).

    Raises:
        error: ``ref`` has no ``:``, or the module or attribute does not import (the cause named).
    """
    module, sep, attr = ref.partition(":")
    if not sep or not module or not attr:
        raise error(f"{ref!r} is not a 'module:attr' reference")
    try:
        obj: Any = importlib.import_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as e:
        raise error(f"{ref!r} does not name an importable object ({e})") from e
    return obj


class Registry(Mapping[str, T], Generic[T]):
    """Named entries of one kind, in registration order.

    Args:
        kind: what an entry is, for messages (``"IRL method"``, ``"driver format"``).
        error: the class raised (:class:`RegistryError` or a subclass of it).
        check: ``check(name, entry)`` run on each entry when registered (lazy entries: when first
            imported); raises ``error`` (or any exception) to refuse it.
    """

    def __init__(self, kind: str, *, error: type[RegistryError] = RegistryError,
                 check: Callable[[str, T], None] | None = None) -> None:
        if not issubclass(error, RegistryError):
            raise TypeError(f"Registry error class must subclass RegistryError, got {error.__name__}")
        self.kind = kind
        self.error = error
        self._check = check
        self._entries: dict[str, T | str] = {}

    def register(self, name: str, entry: T | str, *, replace: bool = False) -> T | str:
        """Add ``entry`` (an object or a ``"module:attr"`` string) under ``name``, after the others;
        returns ``entry``.

        Raises:
            RegistryError (``self.error``): an empty name, or ``name`` registered already and not
                ``replace``; ``check``'s refusal of an object entry.
        """
        if not isinstance(name, str) or not name.strip():
            raise self.error(f"{self.kind} {name!r}: an entry needs a name (non-empty)")
        if name in self._entries and not replace:
            raise self.error(f"{self.kind} {name!r} is registered already")
        if self._check is not None and not isinstance(entry, str):
            self._check(name, entry)
        self._entries[name] = entry
        return entry

    def unregister(self, name: str) -> None:
        """Remove ``name`` (nothing if absent)."""
        self._entries.pop(name, None)

    def pop(self, name: str, *default: Any) -> Any:
        """Remove ``name`` and return its entry (resolved), as :meth:`dict.pop`."""
        if name not in self._entries:
            if default:
                return default[0]
            raise self._unknown(name)
        value = self[name]
        del self._entries[name]
        return value

    def get(self, name: str, default: Any = None) -> Any:
        """The entry of ``name`` (imported if lazy), or ``default`` if no such name; a lazy entry
        that does not import raises (see :meth:`__getitem__`)."""
        return self[name] if name in self._entries else default

    def names(self) -> tuple[str, ...]:
        """The registered names, in registration order."""
        return tuple(self._entries)

    def _unknown(self, name: object) -> RegistryError:
        return self.error(f"unknown {self.kind} {name!r}; expected one of: {', '.join(self._entries) or '(none)'}")

    def __getitem__(self, name: object) -> T:
        """The entry of ``name``, imported if registered as ``"module:attr"``.

        Raises:
            RegistryError (``self.error``): an unknown name (the known ones listed), or a lazy entry
                that does not import or that ``check`` refuses.
        """
        if not isinstance(name, str) or name not in self._entries:
            raise self._unknown(name)
        entry = self._entries[name]
        if isinstance(entry, str):
            obj: T = resolve_ref(entry, self.error)
            if self._check is not None:
                self._check(name, obj)
            self._entries[name] = obj
            return obj
        return entry

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(tuple(self._entries))

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}: {', '.join(self._entries)})"
