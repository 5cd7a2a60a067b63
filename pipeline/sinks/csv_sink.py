"""``tracks.csv`` (MOTChallenge rows) and ``targets.csv`` (per-target status table).

Rows are written whole at each checkpoint of the run loop (``pipeline.runloop``), so after any
fault both files end with a complete row and hold the frames ``summary.json`` reports.

``tracks.csv``: no header; ``frame,id,x,y,w,h,conf,-1,-1,-1`` per target per frame while
the target is tracked or occluded (``conf`` lower when occluded); no row once it is lost
(and none while tentative). Its boxes are 1-based, as MOTChallenge files are (the ``gt.txt``
the project writes and reads is too), so TrackEval and py-motmetrics score a run folder as
it is; ``targets.csv`` keeps the 0-based continuous convention of the rest of dualtrack.

``targets.csv``: header; ``frame,id,status,x_px,y_px,w_px,h_px,source,iterations,rho,
model_update,diagnostics,decision`` for every target every frame. ``iterations`` lists the
iterations per stage (``meanshift=4;levelset=37``), ``model_update`` the model-update decision
and its reason (``updated:rho-high``), ``diagnostics`` named values (``d=0.31;area_px2=812``),
``decision`` the tracker's case for the frame and why (``appearance:appearance-contour-leak``;
empty for trackers without one).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from types import TracebackType

from pipeline.io.groundtruth import MOT_BASE
from pipeline.sinks.rowfile import RowFile
from pipeline.types import FrameResult

TARGETS_HEADER = (
    "frame",
    "id",
    "status",
    "x_px",
    "y_px",
    "w_px",
    "h_px",
    "source",
    "iterations",
    "rho",
    "model_update",
    "diagnostics",
    "decision",
)


def _num(v: float) -> str:
    return f"{v:.3f}" if math.isfinite(v) else ""


def _pairs(d: dict[str, float] | object) -> str:
    items = getattr(d, "items", lambda: [])()
    out = []
    for k, v in items:
        if isinstance(v, float):
            out.append(f"{k}={v:.4g}" if math.isfinite(v) else f"{k}=")
        else:
            out.append(f"{k}={v}")
    return ";".join(out)


class CsvSink:
    """Writes ``tracks.csv`` and ``targets.csv`` into a run folder, in whole rows at each
    checkpoint (``pipeline.sinks.rowfile``)."""

    def __init__(self, out_dir: Path):
        self._tracks = RowFile(out_dir / "tracks.csv")
        self._targets = RowFile(out_dir / "targets.csv")
        self._tw = csv.writer(self._tracks, lineterminator="\n")
        self._gw = csv.writer(self._targets, lineterminator="\n")
        self._gw.writerow(TARGETS_HEADER)
        self._targets.checkpoint()

    def write(self, result: FrameResult) -> None:
        f = result.frame
        for t in result.targets:
            b = t.box
            if t.status.is_reported:
                self._tw.writerow(
                    [
                        f,
                        t.id,
                        _num(b.x + MOT_BASE),
                        _num(b.y + MOT_BASE),
                        _num(b.w),
                        _num(b.h),
                        f"{t.confidence:.3f}",
                        -1,
                        -1,
                        -1,
                    ]
                )
            self._gw.writerow(
                [
                    f,
                    t.id,
                    t.status.value,
                    _num(b.x),
                    _num(b.y),
                    _num(b.w),
                    _num(b.h),
                    t.source,
                    _pairs(t.iterations),
                    _num(t.rho) if not math.isnan(t.rho) else "",
                    t.model_update,
                    _pairs(t.diagnostics),
                    "" if t.decision is None else str(t.decision),
                ]
            )

    def checkpoint(self) -> None:
        """Write every row so far to disk (both files hold the same frames afterwards)."""
        self._tracks.checkpoint()
        self._targets.checkpoint()

    def rollback(self) -> None:
        """Undo the last checkpoint of both files."""
        self._tracks.rollback()
        self._targets.rollback()

    def close(self) -> None:
        try:
            self._tracks.close()
        finally:
            self._targets.close()

    def __enter__(self) -> CsvSink:
        return self

    def __exit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
