"""Tests that need an optional extra, and what happens when it is absent.

* ``rl`` and ``video`` (Stable-Baselines3 with torch, Minari, moviepy): :func:`require_extra`
  imports the module or skips the calling test with the extra's install line; with
  ``MERGE_IRL_REQUIRE_EXTRAS=1`` (CI installs them, ``.ci/run``) it fails instead.
* ``imitation-bench`` (imitation 1.0.1, which pins gymnasium 0.29): tests that need it are
  marked ``imitation`` and call :func:`require_imitation`; CI runs them in a second environment
  with ``MERGE_IRL_REQUIRE_IMITATION=1``, where an absent module fails. In the first environment
  (``rl``, gymnasium 1.x) imitation is not installed and they skip.
"""

import importlib
import os
from types import ModuleType

import pytest

REQUIRE_EXTRAS_ENV = "MERGE_IRL_REQUIRE_EXTRAS"
REQUIRE_IMITATION_ENV = "MERGE_IRL_REQUIRE_IMITATION"


def _set(env: str) -> bool:
    return os.environ.get(env, "") not in ("", "0")


def _require(module: str, install: str, env: str) -> ModuleType:
    try:
        return importlib.import_module(module)
    except ImportError as e:
        msg = f"{module} is not installed ({e}); install it with {install}"
        if _set(env):
            pytest.fail(f"{msg}, and {env} is set: a missing extra is a failure", pytrace=False)
        pytest.skip(f"{msg} (set {env}=1 to fail instead)")


def require_extra(module: str, extra: str) -> ModuleType:
    """``module`` imported; else skip the calling test, or fail it under ``MERGE_IRL_REQUIRE_EXTRAS=1``.

    Args:
        module: the module to import (``"stable_baselines3"``, ``"minari"``, ``"moviepy"``).
        extra: the project extra that installs it (``"rl"``, ``"video"``), for the message.

    Raises:
        pytest.skip.Exception: the import fails (the default).
        pytest.fail.Exception: the import fails and ``MERGE_IRL_REQUIRE_EXTRAS`` is set.
    """
    return _require(module, f"pip install torch==2.13.0 && pip install -e '.[{extra}]'", REQUIRE_EXTRAS_ENV)


def require_imitation(module: str = "imitation") -> ModuleType:
    """``module`` of the imitation-bench extra imported; else skip, or fail under
    ``MERGE_IRL_REQUIRE_IMITATION=1`` (CI's second environment).

    Raises:
        pytest.skip.Exception, pytest.fail.Exception: as :func:`require_extra`.
    """
    return _require(module, "pip install torch==2.13.0 && pip install -e '.[imitation-bench]'",
                    REQUIRE_IMITATION_ENV)
