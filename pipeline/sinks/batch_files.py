"""Run folders that came back from a Dask worker, written under the batch's DIR."""

from __future__ import annotations

import shutil
from pathlib import Path


def write_run_files(run_dir: Path, files: dict[str, bytes]) -> None:
    """Write ``files`` (relative path -> bytes) as ``run_dir``, replacing what was there.

    Written beside it first and renamed, so an interrupted write never leaves a run
    folder that looks complete.
    """
    run_dir = Path(run_dir)
    tmp = run_dir.with_name(run_dir.name + ".incoming")
    if tmp.exists():
        shutil.rmtree(tmp)
    for rel, data in files.items():
        f = tmp / rel
        if ".." in Path(rel).parts or Path(rel).is_absolute():
            raise ValueError(f"refusing to write outside the run folder: {rel}")
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(data)
    if run_dir.exists():
        shutil.rmtree(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp.rename(run_dir)
