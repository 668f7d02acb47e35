import sys
from pathlib import Path

# Test helper modules (e.g. sweep_tasks) are importable by name, also in worker processes.
sys.path.insert(0, str(Path(__file__).parent))


def pytest_configure(config):
    config.addinivalue_line("markers", "hostile: property-based hostile-input suites (hypothesis, bounded)")
    config.addinivalue_line(
        "markers", "others_wip: exercises another helper's code that was still in progress when written")
