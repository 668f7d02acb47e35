import os
import sys
from pathlib import Path

# Test helper modules (e.g. sweep_tasks) are importable by name, also in worker processes.
sys.path.insert(0, str(Path(__file__).parent))


def pytest_configure(config):
    config.addinivalue_line("markers", "hostile: property-based hostile-input suites (hypothesis, bounded)")


# In CI the property-based suites draw the same examples every run, so a red CI is reproducible;
# locally they explore new examples each run.
if os.environ.get("CI"):
    from hypothesis import settings

    settings.register_profile("ci", derandomize=True, print_blob=True)
    settings.load_profile("ci")
