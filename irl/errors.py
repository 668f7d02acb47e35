"""Exceptions raised by ``irl``. Every message names the file, line or field at fault."""


class IRLError(Exception):
    """Base class of every error raised by the ``irl`` package."""


class DemonstrationError(IRLError, ValueError):
    """Demonstrations (a file or arrays) are malformed."""


class ConfigError(IRLError, ValueError):
    """An IRL configuration value is invalid."""


class ModelFileError(IRLError, ValueError):
    """A saved model file is malformed."""


class ConvergenceError(IRLError, RuntimeError):
    """A fixed point (Q of a given theta) could not be computed."""


class EncodingError(DemonstrationError):
    """A value cannot be encoded into a domain's state or action (e.g. NaN where a number is
    required)."""
