import os
import sys
from pathlib import Path

import pytest

# Test helper modules (e.g. sweep_tasks) are importable by name, also in worker processes.
sys.path.insert(0, str(Path(__file__).parent))

from shared_data import RAILUSM, require  # noqa: E402  (needs the path above)


def pytest_configure(config):
    config.addinivalue_line("markers", "hostile: property-based hostile-input suites (hypothesis, bounded)")


@pytest.fixture(scope="session")
def railusm() -> Path:
    """The authors' demonstrations (``railusm/``: ``gridworld/``, ``merge_ngsim/``), not shipped (AGPL).

    Absent, the test skips; under ``MERGE_IRL_REQUIRE_DATA=1`` it fails (see ``shared_data.require``).
    """
    return require(RAILUSM, "the authors' demonstrations (RAILUSM/Model-free-IRL, folder data/)")


# In CI the property-based suites draw the same examples every run, so a red CI is reproducible;
# locally they explore new examples each run.
if os.environ.get("CI"):
    from hypothesis import settings

    settings.register_profile("ci", derandomize=True, print_blob=True)
    settings.load_profile("ci")
