"""The seeds the environments' ``reset`` accepts, and the SUMO seed each one runs.

SUMO takes a seed in ``[0, 2**31)`` (:data:`SUMO_SEED_LIMIT`; the scenario spec's
``simulation.seed``), while Gymnasium's and PettingZoo's ``reset(seed=...)`` take any
non-negative integer, and data collectors draw large ones: Minari's ``DataCollector`` seeds every
``reset`` it is not given a seed for with 64 random bits. :func:`reset_seed` checks a seed the
same way for :class:`sim.env.merge_env.MergeEnv` and
:class:`sim.env.multi_agent.MergeParallelEnv` and maps it into SUMO's range:

* accepted: Python and numpy integers ``>= 0`` of any size (``2**64 - 1``, ``numpy.uint64``);
* refused (:class:`SeedError`, one line naming the seed): ``bool``, floats (``9.7`` and
  ``9.0`` alike), negative integers, strings and every other type;
* the SUMO seed (:func:`sumo_seed`): a seed below ``2**31`` is itself (the seeds of earlier
  results keep their meaning); a larger one is the first 8 bytes of the BLAKE2b hash
  (``hashlib.blake2b``, 8-byte digest) of its decimal digits, as a big-endian integer, modulo
  ``2**31``. The same seed gives the same run on every machine and Python version (no
  ``hash()``, which is salted per process); two large seeds, or a large and a small one, may
  share a SUMO run (about one pair in ``2**31``).

The environment's own generator (``np_random``) is seeded with the seed itself, not the SUMO
seed. :data:`COLLECTOR_OPTIONS` are the ``reset`` options that data collectors send for
themselves (Minari's ``minari_autoseed``), which the environment reads as no option.
"""

from __future__ import annotations

import hashlib
import numbers
from typing import Any, NamedTuple

from sim.errors import SimError

#: SUMO's seeds are ``0 .. SUMO_SEED_LIMIT - 1``.
SUMO_SEED_LIMIT = 2**31
#: ``reset`` options that are a data collector's, not the environment's: Minari's
#: ``DataCollector`` passes its ``options`` on to ``reset`` unchanged, ``minari_autoseed=False``
#: included (its switch that turns its 64-bit seeds off).
COLLECTOR_OPTIONS = frozenset({"minari_autoseed"})


class SeedError(SimError, ValueError, TypeError):
    """A seed ``reset`` refuses (a ``ValueError`` for a negative integer, a ``TypeError`` for a
    bool, float or other type; one class, so both environments refuse alike)."""


class ResetSeed(NamedTuple):
    """A checked seed: ``seed`` (a Python ``int >= 0``, for the environment's generator) and
    ``sumo`` (its SUMO seed, ``0 .. 2**31 - 1``: :func:`sumo_seed`)."""

    seed: int
    sumo: int


def sumo_seed(seed: int) -> int:
    """The SUMO seed of a checked seed ``seed >= 0`` (module docstring: ``seed`` itself below
    ``2**31``, else the BLAKE2b hash of its decimal digits modulo ``2**31``)."""
    if seed < SUMO_SEED_LIMIT:
        return seed
    digest = hashlib.blake2b(str(seed).encode("ascii"), digest_size=8).digest()
    return int.from_bytes(digest, "big") % SUMO_SEED_LIMIT


def reset_seed(seed: Any, where: str) -> ResetSeed | None:
    """``seed`` of ``where``'s ``reset`` checked (None: None, the environment draws one).

    Args:
        seed: a Python or numpy integer ``>= 0`` of any size, or None.
        where: the caller, for the message (``"MergeEnv.reset"``).

    Raises:
        SeedError: a bool, a float, a negative integer or another type (the message names it).
    """
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise SeedError(f"{where}: seed must be an integer >= 0 (any size) or None, got {seed!r} "
                        f"({type(seed).__name__})")
    value = int(seed)
    if value < 0:
        raise SeedError(f"{where}: seed must be an integer >= 0 (any size) or None, got {value}")
    return ResetSeed(value, sumo_seed(value))


def unread_options(options: Any) -> list[str]:
    """The keys of ``options`` (a ``reset``'s; None or a mapping) other than
    :data:`COLLECTOR_OPTIONS`, sorted as strings: the ones the environment would have to read."""
    return sorted(str(k) for k in (options or {}) if k not in COLLECTOR_OPTIONS)
