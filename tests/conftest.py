import sys
from pathlib import Path

# Test helper modules (e.g. sweep_tasks) are importable by name, also in worker processes.
sys.path.insert(0, str(Path(__file__).parent))
