"""Where the tests find their data, and what happens when a data set is absent.

* ``VENDORED`` (``tests/data/``): small real data shipped with the repository (36 NGSIM I-80
  leader-follower pairs, the NGSIM.jl I-80 lane geometry; see ``tests/data/README.md``). Always
  present: tests read it directly.
* ``DATA`` (``<checkout>/../shared/data``; set ``MERGE_IRL_SHARED`` to use another copy of
  ``shared/``): data that does not ship, above all the authors' demonstrations (``railusm/``,
  AGPL, from the ``data/`` folder of RAILUSM/Model-free-IRL). Tests reach it only through
  :func:`require` (or the ``railusm`` fixture of ``conftest.py``): absent, the test skips with
  the reason; with ``MERGE_IRL_REQUIRE_DATA=1`` (CI) it fails instead.

The product itself never reads either.
"""

import os
from pathlib import Path

import pytest

SHARED = Path(os.environ.get("MERGE_IRL_SHARED", Path(__file__).resolve().parents[2] / "shared"))
DATA = SHARED / "data"
RAILUSM = DATA / "railusm"
VENDORED = Path(__file__).resolve().parent / "data"
PAIRS_DIR = VENDORED / "ngsim_i80_car_following"
GEOMETRY_DIR = VENDORED / "i80_geometry"
REQUIRE_DATA_ENV = "MERGE_IRL_REQUIRE_DATA"


def require(path: Path, what: str) -> Path:
    """``path`` if it exists; else skip the calling test, or fail it under ``MERGE_IRL_REQUIRE_DATA=1``.

    Args:
        path: the file or folder the test needs.
        what: the data set, in words, for the message.

    Raises:
        pytest.skip.Exception: ``path`` is absent (the default).
        pytest.fail.Exception: ``path`` is absent and ``MERGE_IRL_REQUIRE_DATA`` is set to a value
            other than ``""`` or ``"0"``.
    """
    if path.exists():
        return path
    msg = f"{what} not found at {path}"
    if os.environ.get(REQUIRE_DATA_ENV, "") not in ("", "0"):
        pytest.fail(f"{msg}, and {REQUIRE_DATA_ENV} is set: missing data is a failure", pytrace=False)
    pytest.skip(f"{msg} (set {REQUIRE_DATA_ENV}=1 to fail instead)")
