"""Per-task seeds derived from a sweep seed and the task's key."""

from __future__ import annotations

import hashlib

import numpy as np


def derive_seed(sweep_seed: int, key: str) -> int:
    """A 63-bit seed that depends only on ``sweep_seed`` and ``key``.

    Uses ``numpy.random.SeedSequence`` with the key's SHA-256 as spawn key, so distinct keys
    give statistically independent streams, whichever process or order runs them.
    """
    digest = hashlib.sha256(key.encode("utf-8")).digest()
    words = tuple(int.from_bytes(digest[i : i + 4], "little") for i in range(0, 32, 4))
    seq = np.random.SeedSequence(entropy=int(sweep_seed), spawn_key=words)
    return int(seq.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))
