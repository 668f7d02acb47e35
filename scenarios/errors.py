"""Exceptions raised by ``scenarios``. Every message names the field at fault."""


class ScenarioError(Exception):
    """Base class of every error raised by the ``scenarios`` package."""


class SpecError(ScenarioError, ValueError):
    """A scenario spec (TOML or dataclass) is invalid; the message names the field."""
