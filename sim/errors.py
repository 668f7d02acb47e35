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


class InputTooLargeError(SimError, MemoryError):
    """Reading or processing an input ran out of memory; the message names the input, the
    allocation that failed and what to do."""


def out_of_memory(e: MemoryError, what: str, advice: str) -> InputTooLargeError:
    """One-line :class:`InputTooLargeError` for ``e`` raised while working on ``what`` (a file):
    the size of the allocation that failed (numpy's and pyarrow's errors say it) and ``advice``."""
    size = getattr(e, "_total_size", None)  # numpy's _ArrayMemoryError: bytes of the refused array
    if isinstance(size, int):
        needed = f"an array of {size / 2**20:.0f} MiB could not be allocated"
    else:
        text = " ".join(str(e).split())
        needed = f"an allocation failed ({text})" if text else "an allocation failed"
    return InputTooLargeError(f"{what}: out of memory: {needed}; {advice}")
