"""Where the tests find ``shared/`` (the paper's data, NGSIM pairs, I-80 geometry).

``shared/`` sits beside the repository checkout (``<checkout>/../shared``), in CI too; set
``MERGE_IRL_SHARED`` to use another copy. The product itself never reads it.
"""

import os
from pathlib import Path

SHARED = Path(os.environ.get("MERGE_IRL_SHARED", Path(__file__).resolve().parents[2] / "shared"))
DATA = SHARED / "data"
