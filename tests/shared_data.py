"""Where the workplace's shared reference data lives, for tests and benchmarks only.

The stock ROBOTIS action file is reference data that the project must never ship: it stays in
``shared/data`` beside the checkout (CI clones the project next to ``shared/``), or wherever
``DARWIN_SHARED_DATA`` points.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("DARWIN_SHARED_DATA", REPO.parent / "shared" / "data"))
STOCK_MOTIONS = SHARED_DATA / "motion_4096.bin"
STOCK_MOTIONS_MD5 = "207d160ede2c9329017df6151497db65"
