"""Ground-truth and box-file parsing.

Every parser returns boxes in the convention of ``pipeline.types`` (continuous, 0-based
``x, y, w, h``); frames without truth are rows of NaN. Values may be integers or floats
separated by commas, spaces or tabs (mixed is fine). Accepted row forms:

* 4 numbers, ``x y w h`` (``form="xywh"``) or ``x1 y1 x2 y2`` (``form="xyxy"``);
* 8 numbers, a polygon ``x1 y1 ... x4 y4``: its axis-aligned bounding box;
* a row of NaN, or a box with ``w <= 0`` or ``h <= 0``: no truth in that frame
  (LasHeR marks absent targets this way, VOT writes ``0,0,0,0``).

``base`` is the coordinate of the first pixel's corner in the file's convention
subtracted on the way in: 1 for OTB-style and MOTChallenge files, 0 otherwise.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.errors import InputError

_SPLIT = re.compile(r"\s*[,;]\s*|\s+")  # one comma or semicolon, or a run of blanks
MOT_BASE = 1.0
"""Coordinate of the first pixel's corner in MOTChallenge files (``gt.txt``, ``det.txt``,
``tracks.csv``)."""


def _numbers(path: Path, lineno: int, line: str) -> list[float]:
    parts = _SPLIT.split(line.strip().rstrip(",;").strip())
    if "" in parts:
        raise InputError(
            f"{path}:{lineno}: malformed ground truth, an empty field (two separators in a row)"
        )
    try:
        return [float(p) for p in parts]
    except ValueError:
        bad = next(p for p in parts if not _is_float(p))
        raise InputError(
            f"{path}:{lineno}: malformed ground truth, {bad!r} is not a number"
        ) from None


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def read_text(path: Path, not_text: str, name: str | None = None) -> str:
    """The text of ``path`` (UTF-8; a byte-order mark dropped).

    Raises
    ------
    InputError
        ``not_text`` for bytes that are not UTF-8 text; ``cannot read <name>: <reason>`` (name
        defaults to the path) when the system cannot read the file.
    """
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(not_text) from None
    except OSError as exc:
        raise InputError(f"cannot read {name or path}: {exc.strerror}") from None


def _read_lines(path: Path) -> list[str]:
    text = read_text(path, f"{path}: malformed ground truth, not a text file")
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def row_to_box(values: list[float], form: str, base: float) -> tuple[float, float, float, float]:
    """Convert one row of numbers (4 or 8) to an ``(x, y, w, h)`` tuple (NaNs when absent)."""
    nan = (math.nan,) * 4
    if any(math.isnan(v) for v in values):
        return nan
    if len(values) == 8:
        xs, ys = values[0::2], values[1::2]
        x1, y1, x2, y2 = min(xs), min(ys), max(xs), max(ys)
        w, h = x2 - x1, y2 - y1
        x, y = x1, y1
    elif form == "xyxy":
        x, y = values[0], values[1]
        w, h = values[2] - values[0], values[3] - values[1]
    else:
        x, y, w, h = values[:4]
    if not (w > 0 and h > 0) or any(math.isinf(v) for v in (x, y, w, h)):
        return nan
    return (x - base, y - base, w, h)


def parse_box_file(path: Path, form: str = "xywh", base: float = 0.0) -> np.ndarray:
    """Parse a per-frame box file into an ``(N, 4)`` float64 array (NaN rows = no truth).

    Parameters
    ----------
    path : Path
        One box per line.
    form : {"xywh", "xyxy"}
        Meaning of 4-number rows.
    base : float
        Subtracted from x and y (1 for 1-based files).

    Raises
    ------
    InputError
        On a line that is not 4 or 8 numbers, naming the file and line.
    """
    if form not in ("xywh", "xyxy"):
        raise ValueError(f"form must be 'xywh' or 'xyxy'; got {form!r}")
    rows = []
    for lineno, line in enumerate(_read_lines(path), start=1):
        if not line.strip():
            rows.append((math.nan,) * 4)
            continue
        values = _numbers(path, lineno, line)
        if len(values) not in (4, 8):
            raise InputError(
                f"{path}:{lineno}: malformed ground truth, expected 4 (box) or 8 (polygon) "
                f"numbers, got {len(values)}"
            )
        rows.append(row_to_box(values, form, base))
    if not rows:
        raise InputError(f"{path}: ground-truth file is empty")
    return np.asarray(rows, dtype=np.float64)


@dataclass(frozen=True)
class MotTruth:
    """Many-target truth from a MOTChallenge ``gt.txt``.

    ``boxes[id]`` is ``(N, 4)`` (NaN where the target is absent) and ``visibility[id]``
    ``(N,)`` in [0, 1] (1 where the file has no visibility column).
    """

    boxes: dict[int, np.ndarray]
    visibility: dict[int, np.ndarray] = field(default_factory=dict)
    last_frame: int = 0  # the largest frame number in the file
    distractors: dict[int, np.ndarray] = field(
        default_factory=dict
    )  # DISTRACTOR_CLASSES rows, (N, 4) per id
    duplicates: tuple[tuple[int, int], ...] = ()  # (frame, id) of rows that repeat an earlier one


DISTRACTOR_CLASSES = (2, 7, 8, 12)
"""MOTChallenge classes whose matched tracker boxes are neither true nor false positives
(TrackEval's MOT17 preprocessing: person on vehicle, static person, distractor, reflection)."""


def parse_mot_rows(
    path: Path, base: float = 1.0
) -> list[tuple[int, int, tuple[float, float, float, float], float, float]]:
    """Rows ``(frame, id, box, flag, visibility)`` of a MOTChallenge-style file.

    Columns: ``frame,id,x,y,w,h[,flag/conf[,class[,visibility]]]``.
    """
    return [(f, t, b, flag, v) for f, t, b, flag, _cls, v in _mot_rows(path, base)]


def _mot_rows(
    path: Path, base: float
) -> list[tuple[int, int, tuple[float, float, float, float], float, int, float]]:
    """Rows ``(frame, id, box, flag, class, visibility)``; class 1 where the file has no class
    column."""
    out = []
    for lineno, line in enumerate(_read_lines(path), start=1):
        if not line.strip():
            continue
        values = _numbers(path, lineno, line)
        if len(values) < 6:
            raise InputError(
                f"{path}:{lineno}: malformed MOT row, expected at least 6 numbers "
                f"(frame,id,x,y,w,h), got {len(values)}"
            )
        frame, tid = values[0], values[1]
        if frame != int(frame) or tid != int(tid) or frame < 1:
            raise InputError(
                f"{path}:{lineno}: malformed MOT row, frame and id must be integers, frame >= 1"
            )
        box = row_to_box(values[2:6], "xywh", base)
        flag = values[6] if len(values) > 6 else 1.0
        cls = int(values[7]) if len(values) > 7 and math.isfinite(values[7]) else 1
        vis = values[8] if len(values) > 8 else 1.0
        out.append((int(frame), int(tid), box, flag, cls, vis))
    return out


def parse_mot_truth(path: Path, n_frames: int, base: float = 1.0) -> MotTruth:
    """Parse a MOTChallenge ``gt.txt``.

    A (frame, id) given twice keeps its last row; ``MotTruth.duplicates`` lists the repeats.
    Rows with flag 0 are not truth, as MOTChallenge reads them; those of a distractor class
    (:data:`DISTRACTOR_CLASSES`, class column 8 in the random scenes: objects that are not
    targets) go to ``MotTruth.distractors``, which the many-target scores use as TrackEval
    does (``pipeline.eval.mot.drop_distractor_matches``).
    """
    boxes: dict[int, np.ndarray] = {}
    vis: dict[int, np.ndarray] = {}
    distractors: dict[int, np.ndarray] = {}
    last = 0
    seen: set[tuple[int, int]] = set()
    dup: list[tuple[int, int]] = []
    for frame, tid, box, flag, cls, v in _mot_rows(path, base):
        last = max(last, frame)
        if (frame, tid) in seen:
            dup.append((frame, tid))
        seen.add((frame, tid))
        if frame > n_frames:
            continue
        if cls in DISTRACTOR_CLASSES:
            distractors.setdefault(tid, np.full((n_frames, 4), np.nan))[frame - 1] = box
            continue
        if flag == 0:
            continue
        if tid not in boxes:
            boxes[tid] = np.full((n_frames, 4), np.nan)
            vis[tid] = np.zeros(n_frames)
        boxes[tid][frame - 1] = box
        vis[tid][frame - 1] = min(max(v, 0.0), 1.0) if not math.isnan(box[0]) else 0.0
    if not boxes:
        raise InputError(f"{path}: no ground-truth rows")
    return MotTruth(
        dict(sorted(boxes.items())),
        dict(sorted(vis.items())),
        last,
        dict(sorted(distractors.items())),
        tuple(dup),
    )


def expand_sparse(boxes: np.ndarray, n_frames: int, every: int) -> np.ndarray:
    """Place annotations made every ``every`` frames (VTUAV: 10) at frames 1, 1+every, ..."""
    out = np.full((n_frames, 4), np.nan)
    idx = np.arange(boxes.shape[0]) * every
    keep = idx < n_frames
    out[idx[keep]] = boxes[keep]
    return out


def fit_length(boxes: np.ndarray, n_frames: int) -> np.ndarray:
    """Truncate or NaN-pad a truth array to the sequence length."""
    if boxes.shape[0] >= n_frames:
        return boxes[:n_frames]
    pad = np.full((n_frames - boxes.shape[0], 4), np.nan)
    return np.vstack([boxes, pad])
