"""Exceptions raised by ``sim``. Every message names the file, row or field at fault."""


class SimError(Exception):
    """Base class of every error raised by the ``sim`` package."""


class TrajectoryFormatError(SimError, ValueError):
    """A trajectory file or table does not follow the NGSIM schema."""


class SimulationError(SimError, RuntimeError):
    """SUMO failed or was interrupted."""


class RewardError(SimError, ValueError):
    """An environment reward returned something that is not one finite real number."""


class ObservationError(SimError, ValueError):
    """An environment observation returned an array that does not fit its own space's shape."""
