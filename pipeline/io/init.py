"""Initial targets, by the rules of docs/formats.md (first rule that applies):

1. ``--init x,y,w,h`` (repeatable; ids 1..N in order);
2. ``--init-file F``: one ``x,y,w,h`` per line, or MOT rows of frame 1 (ids from the file);
3. ``--detect``: automatic detection (handled by the runner);
4. the sequence's own first-frame truth: every id present in frame 1 of ``gt.txt``, else
   the first box of the single-target truth (visible when both channels have it), else
   the sequence's ``init.txt``.

Boxes are 0-based continuous ``x, y, w, h`` px. A box that lies partly outside the frame
is clipped to it; one entirely outside, or with ``w <= 0`` or ``h <= 0``, is an error.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pipeline.errors import InputError
from pipeline.io.groundtruth import MOT_BASE, parse_box_file, parse_mot_rows, read_text
from pipeline.io.sequence import Sequence
from pipeline.types import BBox, InitTarget


def parse_box_arg(text: str) -> BBox:
    """Parse ``"x,y,w,h"`` (commas or spaces) into a BBox."""
    parts = [p for p in text.replace(",", " ").split() if p]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"--init {text!r}: expected four numbers x,y,w,h") from None
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise InputError(f"--init {text!r}: expected four numbers x,y,w,h")
    return BBox(*vals)


def read_init_file(path: Path) -> list[InitTarget]:
    """Targets from a file of ``x,y,w,h`` lines or MOT rows (only frame 1 is used)."""
    if not path.is_file():
        raise InputError(
            f"--init-file not found: {path}"
            if not path.exists()
            else f"--init-file {path} is not a file"
        )
    text = read_text(
        path,
        f"--init-file {path}: not a text file (one x,y,w,h per line, or MOT rows)",
        f"--init-file {path}",
    )
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    n_cols = len([p for p in first.replace(",", " ").split() if p])
    if n_cols >= 6:
        rows = parse_mot_rows(path, base=MOT_BASE)  # MOTChallenge rows are 1-based
        out = [InitTarget(tid, BBox(*box)) for frame, tid, box, _flag, _vis in rows if frame == 1]
        if not out:
            raise InputError(f"{path}: no MOT rows for frame 1")
        return out
    boxes = parse_box_file(path, "xywh", 0.0)
    out = []
    for i, b in enumerate(boxes, start=1):
        if np.isnan(b).any():
            raise InputError(f"{path}:{i}: init box must have positive width and height")
        out.append(InitTarget(i, BBox(*b)))
    return out


def validate_init(targets: list[InitTarget], width: int, height: int) -> list[InitTarget]:
    """Clip boxes to the frame; reject empty or outside ones with a clear error."""
    if not targets:
        raise InputError("no initial targets")
    ids = [t.id for t in targets]
    if len(set(ids)) != len(ids):
        raise InputError(f"initial target ids must be unique; got {ids}")
    out = []
    for t in targets:
        b = t.box
        if not (b.w > 0 and b.h > 0) or not b.is_valid():
            raise InputError(f"init box of target {t.id} {b} must have positive width and height")
        c = b.clip(width, height)
        if c.area <= 0:
            raise InputError(
                f"init box of target {t.id} {b} lies outside the {width}x{height} frame"
            )
        if c.w < 2 or c.h < 2:
            part = "its part inside the frame is" if c != b else "it is"
            raise InputError(
                f"init box of target {t.id} {b} is too small to track: {part} {c.w:g}x{c.h:g} px, "
                "at least 2x2 is needed"
            )
        out.append(InitTarget(t.id, c))
    return out


def truth_init(seq: Sequence, channel: str | None = None) -> list[InitTarget]:
    """Initial targets from the sequence's own truth (see the module doc, rule 4)."""
    truth = seq.truth
    if truth.multi:
        ch = truth.primary_channel()
        assert ch is not None
        out = [
            InitTarget(tid, BBox(*b[0]))
            for tid, b in truth.boxes[ch].items()
            if not np.isnan(b[0]).any()
        ]
        if out:
            return out
    elif truth.has_truth:
        ch = channel if channel in truth.boxes else truth.primary_channel()
        assert ch is not None
        b = truth.boxes[ch][1][0]
        if not np.isnan(b).any():
            return [InitTarget(1, BBox(*b))]
    if seq.init_file is not None:
        boxes = parse_box_file(seq.init_file, "xywh", 0.0)
        if boxes.shape[0] and not np.isnan(boxes[0]).any():
            return [InitTarget(1, BBox(*boxes[0]))]
    raise InputError(
        f"no initial target for {seq.path}: the sequence has no first-frame ground truth; "
        "give --init x,y,w,h, --init-file FILE or --detect"
    )


def resolve_init(
    seq: Sequence,
    init: list[str] | list[BBox] | list[tuple[float, float, float, float]] | None = None,
    init_file: str | Path | None = None,
    channel: str | None = None,
) -> list[InitTarget]:
    """Apply rules 1, 2 and 4 of the module doc and validate the result (``init`` items are
    ``"x,y,w,h"`` strings, :class:`BBox` or ``(x, y, w, h)`` tuples; ids 1..N)."""
    if init:

        def box(item: object) -> BBox:
            if isinstance(item, BBox):
                return item
            if isinstance(item, str):
                return parse_box_arg(item)
            try:
                x, y, w, h = (float(v) for v in item)  # type: ignore[attr-defined]
            except (TypeError, ValueError):
                raise InputError(f"an initial box must be x,y,w,h; got {item!r}") from None
            return BBox(x, y, w, h)

        targets = [InitTarget(i, box(s)) for i, s in enumerate(init, start=1)]
    elif init_file is not None:
        targets = read_init_file(Path(init_file))
    else:
        targets = truth_init(seq, channel)
    return validate_init(targets, seq.width, seq.height)
