"""``summary.json``: written at the start of a run (``complete: false``) and rewritten at the end.

Each write goes to a temporary file that replaces the old one, so the file is always valid JSON.
"""

from __future__ import annotations

import json
import os
from pathlib import Path


def write_json(path: Path, data: dict[str, object]) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    os.replace(tmp, path)
