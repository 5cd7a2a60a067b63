"""Outputs of ``dualtrack detect``: ``det.txt``, ``rois.csv`` and ``detections.rrd``.

* ``det.txt``: MOTChallenge detection rows ``frame,-1,x,y,w,h,conf,-1,-1,-1`` (1-based boxes,
  as MOTChallenge files and ``tracks.csv`` are), one per accepted ROI, ``conf`` its score
  (:func:`pipeline.stages.detection.score_regions`);
* ``rois.csv``: header; every region found, accepted or not, with its features
  ``frame,x_px,y_px,w_px,h_px,cx_px,cy_px,perimeter_px,area_px,aspect,c1_per_px,c2,accepted,reason,
  contrast_sigma,score`` (the last two for accepted regions);
* ``detections.rrd``: the frame (``<channel>/image``, source bytes), the STDM
  (``<channel>/std_map``, JPEG, scaled so that the detection floor is mid-grey), the
  accepted ROIs (``<channel>/rois``, green) and the rejected ones with their reason
  (``<channel>/rejected``, red), their outlines (``<channel>/roi_contours``), and the count
  per frame (``metrics/detections``).

Rows are flushed every frame: an interrupted run leaves valid files.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from pipeline.errors import OutputError
from pipeline.io.groundtruth import MOT_BASE
from pipeline.sinks.rowfile import RowFile
from pipeline.stages.detection import Detections, Region

ROI_HEADER = (
    "frame",
    "x_px",
    "y_px",
    "w_px",
    "h_px",
    "cx_px",
    "cy_px",
    "perimeter_px",
    "area_px",
    "aspect",
    "c1_per_px",
    "c2",
    "accepted",
    "reason",
    "contrast_sigma",
    "score",
)


class DetectionFiles:
    """``det.txt`` and ``rois.csv``."""

    def __init__(self, out: Path):
        self._det = RowFile(out / "det.txt")
        self._rois = RowFile(out / "rois.csv")
        self._w = csv.writer(self._rois, lineterminator="\r\n")
        self._w.writerow(ROI_HEADER)
        self._rois.checkpoint()

    def write(self, frame: int, d: Detections) -> None:
        for r in d.regions:
            b = r.box
            conf = r.score if r.score == r.score else min(1.0, 1.0 / max(r.c2, 1.0))
            x, y = b.x + MOT_BASE, b.y + MOT_BASE
            self._det.add(f"{frame},-1,{x:.2f},{y:.2f},{b.w:.2f},{b.h:.2f},{conf:.3f},-1,-1,-1")
        for r in (*d.regions, *d.rejected):
            self._w.writerow(_row(frame, r))

    def checkpoint(self) -> None:
        """Write every row so far in whole rows (``pipeline.sinks.rowfile``)."""
        self._det.checkpoint()
        self._rois.checkpoint()

    def rollback(self) -> None:
        """Undo the last checkpoint of both files."""
        self._det.rollback()
        self._rois.rollback()

    def close(self) -> None:
        try:
            self._det.close()
        finally:
            self._rois.close()


def _row(frame: int, r: Region) -> list[object]:
    b = r.box
    return [
        frame,
        f"{b.x:.1f}",
        f"{b.y:.1f}",
        f"{b.w:.1f}",
        f"{b.h:.1f}",
        f"{r.centroid[0]:.2f}",
        f"{r.centroid[1]:.2f}",
        f"{r.perimeter_px:.1f}",
        r.area_px,
        f"{r.aspect:.3f}",
        f"{r.c1:.4f}",
        f"{r.c2:.3f}",
        int(r.accepted),
        r.reason,
        "" if r.contrast != r.contrast else f"{r.contrast:.2f}",
        "" if r.score != r.score else f"{r.score:.3f}",
    ]


class DetectionRecording:
    """``detections.rrd``."""

    def __init__(self, path: Path, channel: str, name: str, min_std: float):
        import rerun as rr
        import rerun.blueprint as rrb

        self.rr = rr
        self.channel = channel
        self.scale = 127.0 / max(min_std, 1e-6)
        self.path = path
        self.rec = rr.RecordingStream("dualtrack", recording_id=f"detect-{name}")
        bp = rrb.Blueprint(
            rrb.Vertical(
                rrb.Horizontal(
                    rrb.Spatial2DView(
                        origin=f"/{channel}",
                        name="ROIs",
                        contents=[
                            f"/{channel}/image",
                            f"/{channel}/rois",
                            f"/{channel}/rejected",
                            f"/{channel}/roi_contours",
                        ],
                    ),
                    rrb.Spatial2DView(
                        origin=f"/{channel}",
                        name="STDM",
                        contents=[f"/{channel}/std_map", f"/{channel}/rois"],
                    ),
                ),
                rrb.TimeSeriesView(origin="/metrics", name="Detections per frame"),
                row_shares=[3, 1],
            )
        )
        self.rec.save(str(path), default_blueprint=bp)

    def write(
        self, frame: int, encoded: tuple[bytes, str] | None, image: np.ndarray, d: Detections
    ) -> None:
        import cv2

        rr, c = self.rr, self.channel
        self.rec.set_time("frame", sequence=frame)
        if encoded is not None:
            self.rec.log(f"{c}/image", rr.EncodedImage(contents=encoded[0], media_type=encoded[1]))
        else:
            _, jpg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
            self.rec.log(
                f"{c}/image", rr.EncodedImage(contents=jpg.tobytes(), media_type="image/jpeg")
            )
        smap = np.clip(d.std_map * self.scale, 0, 255).astype(np.uint8)
        _ok, jpg = cv2.imencode(".jpg", smap, [cv2.IMWRITE_JPEG_QUALITY, 80])
        self.rec.log(
            f"{c}/std_map", rr.EncodedImage(contents=jpg.tobytes(), media_type="image/jpeg")
        )
        for name, regs, color in (
            ("rois", d.regions, (60, 220, 60)),
            ("rejected", d.rejected, (230, 60, 60)),
        ):
            if regs:
                self.rec.log(
                    f"{c}/{name}",
                    rr.Boxes2D(
                        array=np.array([r.box.as_tuple() for r in regs], np.float32),
                        array_format=rr.Box2DFormat.XYWH,
                        colors=[color] * len(regs),
                        labels=[
                            f"P={r.perimeter_px:.0f} C2={r.c2:.1f}" if r.accepted else r.reason
                            for r in regs
                        ],
                    ),
                )
            else:
                self.rec.log(f"{c}/{name}", rr.Clear(recursive=False))
        strips = [np.vstack([r.contour, r.contour[:1]]) for r in d.regions if len(r.contour) >= 2]
        self.rec.log(
            f"{c}/roi_contours",
            rr.LineStrips2D(strips, colors=[(60, 220, 60)])
            if strips
            else rr.Clear(recursive=False),
        )
        self.rec.log("metrics/detections", rr.Scalars(float(len(d.regions))))

    def checkpoint(self) -> None:
        """Wait until what was logged reaches the file."""
        try:
            self.rec.flush(timeout_sec=10.0)
        except RuntimeError as exc:
            raise OutputError(f"cannot write {self.path}: {exc} (is the disk full?)") from None

    def close(self) -> None:
        """Flush and close the file; a writer stuck on a full disk is waited for a bounded
        time (:func:`pipeline.sinks.rerun_sink.disconnect_within`)."""
        from pipeline.sinks.rerun_sink import DISCONNECT_TIMEOUT_S, disconnect_within

        try:
            self.rec.flush(timeout_sec=10.0)
        except RuntimeError as exc:
            raise OutputError(f"cannot write {self.path}: {exc} (is the disk full?)") from None
        finally:
            disconnect_within(self.rec, DISCONNECT_TIMEOUT_S)
