"""Reading tracker results back: our ``tracks.csv`` or a per-frame box file.

``tracks.csv`` holds MOTChallenge rows ``frame,id,x,y,w,h,conf,-1,-1,-1``, 1-based as MOTChallenge
files are (the ``gt.txt`` beside it is too), so TrackEval and py-motmetrics read a run folder as it
is; they are read back into the 0-based continuous convention. A file of one ``x,y,w,h`` (or
8-value polygon) per line, as the single-object toolkits write, is read as target 1, line k = frame
k; a row of zeros or NaN means no output in that frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.errors import InputError
from pipeline.io.groundtruth import MOT_BASE, parse_box_file, parse_mot_rows, read_text


@dataclass(frozen=True)
class TrackTable:
    """Results per track id: ``boxes[id]`` is ``(N, 4)`` with NaN rows where nothing was output."""

    boxes: dict[int, np.ndarray]
    confidence: dict[int, np.ndarray]
    warnings: tuple[str, ...] = ()


def read_tracks(path: str | Path, n_frames: int, base: float | None = None) -> TrackTable:
    """Read ``tracks.csv`` (MOT rows) or a per-frame box file for a sequence of ``n_frames``.

    ``base`` is the file's coordinate base (the coordinate of the first pixel's corner: 0 or
    1); default 1 for MOT rows, as MOTChallenge writes them, and 0 for a per-frame box file, as
    the single-object toolkits write (OTB's own truth files are 1-based: give 1).
    """
    if base is not None and base not in (0, 1):
        raise InputError(
            f"the results' coordinate base must be 0 or 1 (--results-base); got {base:g}"
        )
    p = Path(path)
    if not p.is_file():
        raise InputError(
            f"results file not found: {p}" if not p.exists() else f"results file {p} is a folder"
        )
    text = read_text(p, f"{p}: not a text results file (MOT rows or one x,y,w,h per line)")
    first = next((ln for ln in text.splitlines() if ln.strip()), None)
    if first is None:
        return TrackTable({}, {})
    n_cols = len([c for c in first.replace(",", " ").split() if c])
    if n_cols in (4, 8):
        arr = parse_box_file(p, "xywh", 0.0 if base is None else base)
        if arr.shape[0] > n_frames:
            raise InputError(
                f"{p}: {arr.shape[0]} result lines for a sequence of {n_frames} frames"
            )
        boxes = np.full((n_frames, 4), np.nan)
        boxes[: arr.shape[0]] = arr
        short = (
            (
                f"{p} has {arr.shape[0]} lines for {n_frames} frames; the frames past them have "
                "no output",
            )
            if arr.shape[0] < n_frames
            else ()
        )
        return TrackTable({1: boxes}, {1: np.where(np.isnan(boxes[:, 0]), np.nan, 1.0)}, short)
    boxes_d: dict[int, np.ndarray] = {}
    conf_d: dict[int, np.ndarray] = {}
    seen: set[tuple[int, int]] = set()
    dup: list[tuple[int, int]] = []
    for frame, tid, box, conf, _vis in parse_mot_rows(p, base=MOT_BASE if base is None else base):
        if frame > n_frames:
            raise InputError(f"{p}: row for frame {frame} but the sequence has {n_frames} frames")
        if (frame, tid) in seen:
            dup.append((frame, tid))
        seen.add((frame, tid))
        if tid not in boxes_d:
            boxes_d[tid] = np.full((n_frames, 4), np.nan)
            conf_d[tid] = np.full(n_frames, np.nan)
        boxes_d[tid][frame - 1] = box
        conf_d[tid][frame - 1] = conf
    warnings = ()
    if dup:
        f, t = dup[0]
        warnings = (
            f"{p}: {len(dup)} duplicate (frame, id) rows, the first frame {f} id {t}; the last "
            "row of each counts",
        )
    return TrackTable(dict(sorted(boxes_d.items())), dict(sorted(conf_d.items())), warnings)
