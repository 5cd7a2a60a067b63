"""The Rerun recording (``run.rrd``): the only module that imports ``rerun``.

Entity paths (docs/formats.md): ``visible/image``, ``infrared/image`` (the source JPEG/PNG bytes
passed through as ``EncodedImage``; frames without source bytes, e.g. from a video, are
JPEG-encoded once), ``visible/targets`` and ``infrared/targets`` (Boxes2D, class id = track id,
label ``T<id> <status>``; occluded boxes, and merged targets other than the merge's foreground, are
drawn with a thinner line), ``infrared/contours`` (LineStrips2D), ``events`` (TextLog),
``targets/<id>/status`` (StateChange), ``targets/<id>/decision`` (StateChange ``case:why``, for
trackers that report one), ``metrics/<id>/center_error_px`` (Scalars, when truth exists),
``timing/<stage>_ms``, and the resolved config as a static ``config`` document. With ground truth,
also ``visible/truth`` and ``infrared/truth`` (Boxes2D, each channel's own truth, white, label ``GT
<id>``), ``metrics/<id>/iou`` (Scalars, beside the centre error) and ``targets/<id>/truth``
(StateChange ``overlap`` / ``failure`` / ``no-truth``, under the target's status, so a frame where
the output misses the truth or is missing shows on the timeline), with a ``failure`` event where a
failure starts.

To keep logging well under 1 ms per frame pair, frames are buffered and written with
``send_columns`` at each checkpoint of the run loop (every ``batch_frames`` frames, at most
about every ``checkpoint_min_seconds``), which also waits for them to reach the file;
:meth:`RerunSink.close` writes what is left and closes the file with its footer, so an
interrupted run leaves a recording that verifies, and a killed one a recording (without
footer) of every frame up to its last checkpoint.
"""

from __future__ import annotations

import json
import os
import threading
import uuid
from collections import defaultdict
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from pipeline.errors import OutputError
from pipeline.io.sequence import FramePair
from pipeline.sinks.settings import RerunConfig
from pipeline.types import FrameResult, FrameTruth, TargetStatus, TruthMatch

APP_ID = "dualtrack"

BUFFER_MAX_FRAMES = 1000
BUFFER_MAX_BYTES = 64 << 20
"""The sink writes its buffer itself, between the run loop's checkpoints (or when used alone),
once it holds this many frames or this many bytes of images."""

PALETTE = (
    (230, 25, 75),
    (60, 180, 75),
    (255, 225, 25),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
    (210, 245, 60),
    (250, 190, 212),
    (0, 128, 128),
    (220, 190, 255),
)
STATUS_COLORS = {
    TargetStatus.TENTATIVE: 0xAAAAAAFF,
    TargetStatus.TRACKING: 0x4CAF50FF,
    TargetStatus.OCCLUDED_PARTIAL: 0xFFC107FF,
    TargetStatus.OCCLUDED_SEVERE: 0xFF7043FF,
    TargetStatus.MERGED: 0x42A5F5FF,
    TargetStatus.LOST: 0xEF5350FF,
}
TRUTH_COLOR = (255, 255, 255)
OVERLAY_COLORS = {
    "prediction": (190, 190, 190),
    "meanshift": (255, 160, 40),
    "appearance": (40, 200, 255),
    "camshift": (200, 120, 255),
    "search": (120, 120, 120),
}
"""Colour of each per-stage candidate box (``<channel>/<stage>``): by stage, not by target, so
that a target's own box is the only one in its colour."""
OVERLAY_NAMES = tuple(OVERLAY_COLORS)
"""The per-stage candidate boxes a tracker may report; hidden in the default view."""
TRUTH_MATCH_COLORS = {
    TruthMatch.OVERLAP: 0x4CAF50FF,
    TruthMatch.FAILURE: 0xEF5350FF,
    TruthMatch.NO_TRUTH: 0x9E9E9EFF,
}
EVENT_LEVEL = {
    "failure": rr.TextLogLevel.WARN,
    "lost": rr.TextLogLevel.WARN,
    "merge": rr.TextLogLevel.INFO,
    "split": rr.TextLogLevel.INFO,
    "warning": rr.TextLogLevel.WARN,
}


def class_id(track_id: int) -> int:
    """Rerun class ids are uint16; track ids beyond that wrap (labels keep the real id)."""
    return track_id % 65536


def track_color(track_id: int) -> tuple[int, int, int]:
    return PALETTE[(track_id - 1) % len(PALETTE)]


def blueprint(
    channels: tuple[str, ...],
    target_ids: list[int] | tuple[int, ...] = (),
    has_truth: bool = False,
) -> rrb.Blueprint:
    """Default layout: the channels side by side (truth boxes with them), time series and events
    below; with truth the centre error and the IoU of ``target_ids`` side by side."""
    # the per-stage candidate boxes are left out of the default view (the entity tree adds
    # them): a target's own box, its contour and the truth are what a first look needs
    views = [
        rrb.Spatial2DView(
            origin=f"/{c}",
            name=c.capitalize(),
            contents=["$origin/**", *(f"- $origin/{n}" for n in OVERLAY_NAMES)],
        )
        for c in channels
    ]
    series: list[rrb.View] = []
    if has_truth:
        ids = sorted(target_ids)
        series.append(
            rrb.TimeSeriesView(
                origin="/metrics",
                name="Centre error [px]",
                contents=["+ /metrics/**", *(f"- /metrics/{i}/iou" for i in ids)],
            )
        )
        series.append(
            rrb.TimeSeriesView(
                origin="/metrics",
                name="IoU with the truth",
                contents=[f"+ /metrics/{i}/iou" for i in ids] or ["- /metrics/**"],
            )
        )
    events = rrb.TextLogView(
        origin="/events",
        name="Events",
        columns=rrb.TextLogColumns(
            timeline_columns=[rrb.encodings.TimelineColumn("frame")],
            text_log_columns=[
                rrb.encodings.TextLogColumn("Body"),
                rrb.encodings.TextLogColumn("EntityPath", visible=False),
                rrb.encodings.TextLogColumn("LogLevel", visible=False),
            ],
        ),
    )
    bottom = rrb.Horizontal(
        *series,
        events,
        rrb.StateTimelineView(origin="/targets", name="Status and truth match"),
        rrb.TimeSeriesView(
            origin="/timing", name="Stage time [ms]", plot_legend=rrb.PlotLegend(visible=False)
        ),
        column_shares=[3] * len(series) + [5, 3, 2],
    )
    return rrb.Blueprint(
        rrb.Vertical(rrb.Horizontal(*views), bottom, row_shares=[3, 2]), collapse_panels=True
    )


class RerunSink:
    """Writes one ``run.rrd``; use as a context manager or call :meth:`close`."""

    def __init__(
        self,
        path: Path,
        channels: tuple[str, ...],
        target_ids: list[int],
        cfg: RerunConfig,
        recording_name: str,
        config: dict[str, object] | None = None,
        has_truth: bool = False,
        start_message: str | None = None,
    ):
        self.cfg = cfg
        self.channels = channels
        self.path = path
        self.rec = rr.RecordingStream(
            APP_ID, recording_id=f"{recording_name}-{uuid.uuid4().hex[:12]}"
        )
        self._blueprint_ids = tuple(sorted(target_ids))
        self.rec.save(
            str(path), default_blueprint=blueprint(channels, self._blueprint_ids, has_truth)
        )
        self._match: dict[int, TruthMatch] = {}
        self._buf: dict[str, list] = defaultdict(list)
        self._frames: list[int] = []
        self._bytes = 0  # of the buffered images
        self._status: dict[int, TargetStatus] = {}
        self._decision: dict[int, str] = {}
        self._known_ids: set[int] = set()
        self._closed = False
        self._start_message = start_message
        self._state_config = rr.StateConfiguration(
            values=[st.value for st in TargetStatus],
            labels=[st.value for st in TargetStatus],
            colors=np.array([STATUS_COLORS[st] for st in TargetStatus], np.uint32),
        )
        self._truth_config = rr.StateConfiguration(
            values=[m.value for m in TruthMatch],
            labels=[m.value for m in TruthMatch],
            colors=np.array([TRUTH_MATCH_COLORS[m] for m in TruthMatch], np.uint32),
        )
        self._log_static(target_ids, config, has_truth)
        self._rolled_back = False
        try:  # the header and the static data, whole: what a cut-back recording keeps at least
            self.rec.flush(timeout_sec=10.0)
            self._good_size = path.stat().st_size  # bytes of the file at its last checkpoint
        except (RuntimeError, OSError) as exc:
            disconnect_within(self.rec, DISCONNECT_TIMEOUT_S)
            path.unlink(missing_ok=True)
            raise OutputError(f"cannot write {path}: {exc} (is the disk full?)") from None

    # -- static ---------------------------------------------------------------------
    def _log_static(
        self, target_ids: list[int], config: dict[str, object] | None, has_truth: bool
    ) -> None:
        self._has_truth = has_truth
        self.rec.log("/", rr.AnnotationContext([]), static=True)  # replaced as ids appear
        self._annotate(target_ids)
        if config is not None:
            self.rec.log(
                "config",
                rr.TextDocument(json.dumps(config, indent=2), media_type="text/plain"),
                static=True,
            )

    def _annotate(self, ids: list[int]) -> None:
        new = [i for i in ids if i not in self._known_ids]
        if not new:
            return
        self._known_ids.update(new)
        infos = [
            rr.AnnotationInfo(id=class_id(i), label=f"T{i}", color=track_color(i))
            for i in sorted(self._known_ids)
        ]
        self.rec.log("/", rr.AnnotationContext(infos), static=True)
        for i in new:
            self.rec.log(
                f"metrics/{i}/center_error_px",
                rr.SeriesLines(colors=[track_color(i)], names=[f"T{i}"]),
                static=True,
            )
            self.rec.log(f"targets/{i}/status", self._state_config, static=True)
            if self._has_truth:
                self.rec.log(
                    f"metrics/{i}/iou",
                    rr.SeriesLines(colors=[track_color(i)], names=[f"T{i} IoU"]),
                    static=True,
                )
                self.rec.log(f"targets/{i}/truth", self._truth_config, static=True)

    # -- per frame --------------------------------------------------------------------
    def write(
        self, frames: FramePair, result: FrameResult, truth: FrameTruth | None = None
    ) -> None:
        if self._closed:
            raise RuntimeError("RerunSink is closed")
        f = result.frame
        self._frames.append(f)
        if self._start_message is not None:
            self._buf["events"].append((f, f"[start] {self._start_message}", "start"))
            self._start_message = None
        for ch in self.channels:
            enc = getattr(frames, f"{ch}_encoded")
            if enc is None:
                img = getattr(frames, ch)
                if frames.scale > 1:  # the boxes are in the source's px: show it at its size
                    h, w = img.shape[:2]
                    size = (w * frames.scale, h * frames.scale)
                    img = cv2.resize(img, size, interpolation=cv2.INTER_NEAREST)
                _ok, jpg = cv2.imencode(
                    ".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.cfg.jpeg_quality]
                )
                blob, media = jpg.tobytes(), "image/jpeg"
            else:
                blob, media = enc.data, enc.media_type
            self._buf[f"{ch}/image"].append((f, blob, media))
            self._bytes += len(blob)
        self._annotate([t.id for t in result.targets])
        shown = [t for t in result.targets if t.status != TargetStatus.LOST]
        boxes = [(t.box.cx, t.box.cy, t.box.w / 2, t.box.h / 2) for t in shown]
        self._buf["boxes"].append(
            (
                f,
                boxes,
                [class_id(t.id) for t in shown],
                [f"T{t.id} {t.status.value}" for t in shown],
                [-1.0 if _drawn_thin(t) else -2.5 for t in shown],
            )
        )
        for t in shown:
            for name, ob in t.overlays.items():
                self._buf[f"overlay:{name}"].append((f, t.id, ob))
            for name, v in t.diagnostics.items():
                if isinstance(v, float | int) and np.isfinite(v):
                    self._buf[f"diagnostics/{t.id}/{name}"].append((f, float(v)))
        strips, sids = [], []
        for t in result.targets:
            for c in t.contour:
                if len(c) >= 2:
                    strips.append(np.vstack([c, c[:1]]).astype(np.float32))
                    sids.append(class_id(t.id))
        self._buf["contours"].append((f, strips, sids))
        for t in result.targets:
            if self._status.get(t.id) != t.status:
                self._status[t.id] = t.status
                self._buf[f"targets/{t.id}/status"].append((f, t.status.value))
            text = "" if t.decision is None else str(t.decision)
            if text and self._decision.get(t.id) != text:
                self._decision[t.id] = text
                self._buf[f"targets/{t.id}/decision"].append((f, text))
        for ev in result.events:
            self._buf["events"].append((f, f"[{ev.kind.value}] {ev.text}", ev.kind.value))
        if truth is not None:
            for ch in self.channels:
                tb = truth.boxes.get(ch, {})
                self._buf[f"truth:{ch}"].append(
                    (
                        f,
                        [(b.cx, b.cy, b.w / 2, b.h / 2) for b in tb.values()],
                        [f"GT {i}" for i in tb],
                    )
                )
            for tid, e in truth.center_error_px.items():
                if np.isfinite(e):
                    self._buf[f"metrics/{tid}/center_error_px"].append((f, float(e)))
            for tid, v in truth.iou.items():
                self._buf[f"metrics/{tid}/iou"].append((f, float(v)))
            for tid, m in truth.match.items():
                if self._match.get(tid) != m:
                    if m == TruthMatch.FAILURE:
                        why = (
                            "no output"
                            if not np.isfinite(truth.center_error_px.get(tid, np.inf))
                            else "IoU 0"
                        )
                        self._buf["events"].append(
                            (f, f"[failure] T{tid}: {why} against the truth", "failure")
                        )
                    self._match[tid] = m
                    self._buf[f"targets/{tid}/truth"].append((f, m.value))
        for stage, sec in result.stage_seconds.items():
            self._buf[f"timing/{stage}_ms"].append((f, sec * 1e3))
        # written at checkpoints; a bound between them, and when used alone
        if len(self._frames) >= BUFFER_MAX_FRAMES or self._bytes >= BUFFER_MAX_BYTES:
            self.flush()

    def flush(self) -> None:
        """Write the buffered frames as columns."""
        if not self._frames:
            return
        buf, self._buf, self._frames = self._buf, defaultdict(list), []
        self._bytes = 0
        rec = self.rec
        for key, rows in buf.items():
            if not rows:
                continue
            idx = [rr.TimeColumn("frame", sequence=np.array([r[0] for r in rows], np.int64))]
            if key.endswith("/image"):
                rec.send_columns(
                    key,
                    indexes=idx,
                    columns=rr.EncodedImage.columns(
                        blob=[r[1] for r in rows], media_type=[r[2] for r in rows]
                    ),
                )
            elif key == "boxes":
                lengths = [len(r[1]) for r in rows]
                flat = [b for r in rows for b in r[1]]
                arr = np.asarray(flat, np.float32).reshape(-1, 4)
                cols = rr.Boxes2D.columns(
                    centers=arr[:, :2],
                    half_sizes=arr[:, 2:],
                    class_ids=np.asarray([c for r in rows for c in r[2]], np.uint16),
                    labels=[s for r in rows for s in r[3]],
                    radii=np.asarray([x for r in rows for x in r[4]], np.float32),
                ).partition(lengths)
                for ch in self.channels:
                    rec.send_columns(f"{ch}/targets", indexes=idx, columns=cols)
            elif key.startswith("truth:"):
                lengths = [len(r[1]) for r in rows]
                arr = np.asarray([b for r in rows for b in r[1]], np.float32).reshape(-1, 4)
                white = np.tile(np.asarray(TRUTH_COLOR, np.uint8), (len(arr), 1))
                labels = [s for r in rows for s in r[2]]
                cols = rr.Boxes2D.columns(
                    centers=arr[:, :2],
                    half_sizes=arr[:, 2:],
                    labels=labels,
                    show_labels=np.zeros(len(arr), bool),
                    colors=white,
                    radii=np.full(len(arr), -1.0, np.float32),
                ).partition(lengths)
                ch = key.split(":", 1)[1]
                rec.send_columns(f"{ch}/truth", indexes=idx, columns=cols)
                # the truth's label at its box's top-left corner, apart from the target's label
                # (drawn at the bottom of the target's box)
                corners = arr[:, :2] - arr[:, 2:]
                pts = rr.Points2D.columns(
                    positions=corners,
                    labels=labels,
                    colors=white,
                    radii=np.full(len(arr), 0.5, np.float32),
                ).partition(lengths)
                rec.send_columns(f"{ch}/truth_labels", indexes=idx, columns=pts)
            elif key.startswith("overlay:"):
                name = key.split(":", 1)[1]
                frames_sorted = sorted({r[0] for r in rows})
                per = {fr: [r for r in rows if r[0] == fr] for fr in frames_sorted}
                arr = np.asarray(
                    [
                        [r[2].cx, r[2].cy, r[2].w / 2, r[2].h / 2]
                        for fr in frames_sorted
                        for r in per[fr]
                    ],
                    np.float32,
                ).reshape(-1, 4)
                color = np.asarray(OVERLAY_COLORS.get(name, (160, 160, 160)), np.uint8)
                cols = rr.Boxes2D.columns(
                    centers=arr[:, :2],
                    half_sizes=arr[:, 2:],
                    colors=np.tile(color, (len(arr), 1)),
                    labels=[f"T{r[1]} {name}" for fr in frames_sorted for r in per[fr]],
                    show_labels=np.zeros(len(arr), bool),
                    radii=np.full(len(arr), -0.75, np.float32),
                ).partition([len(per[fr]) for fr in frames_sorted])
                oidx = [rr.TimeColumn("frame", sequence=np.asarray(frames_sorted, np.int64))]
                for ch in self.channels:
                    rec.send_columns(f"{ch}/{name}", indexes=oidx, columns=cols)
            elif key == "contours":
                if "infrared" not in self.channels and not any(r[1] for r in rows):
                    continue
                lengths = [len(r[1]) for r in rows]
                n_strips = sum(lengths)
                cols = rr.LineStrips2D.columns(
                    strips=[s for r in rows for s in r[1]],
                    class_ids=np.asarray([c for r in rows for c in r[2]], np.uint16),
                    show_labels=np.zeros(n_strips, bool),
                ).partition(lengths)
                target = (
                    "infrared/contours"
                    if "infrared" in self.channels
                    else f"{self.channels[0]}/contours"
                )
                rec.send_columns(target, indexes=idx, columns=cols)
            elif key == "events":
                rec.send_columns(
                    "events",
                    indexes=idx,
                    columns=rr.TextLog.columns(
                        text=[r[1] for r in rows],
                        level=[EVENT_LEVEL.get(r[2], rr.TextLogLevel.INFO) for r in rows],
                    ),
                )
            elif key.endswith("/status") or key.endswith("/truth") or key.endswith("/decision"):
                rec.send_columns(
                    key, indexes=idx, columns=rr.StateChange.columns(state=[r[1] for r in rows])
                )
            else:
                rec.send_columns(
                    key,
                    indexes=idx,
                    columns=rr.Scalars.columns(
                        scalars=np.asarray([r[1] for r in rows], np.float64)
                    ),
                )

    def checkpoint(self) -> None:
        """Write the buffered frames and wait until they reach the file (a killed run keeps
        them); the file's size then is where :meth:`rollback` cuts it back to."""
        try:
            self.flush()
            self.rec.flush(timeout_sec=10.0)
        except (
            RuntimeError
        ) as exc:  # the SDK's file writer stopped (a full disk, a removed folder)
            raise OutputError(f"cannot write {self.path}: {exc} (is the disk full?)") from None
        try:
            self._good_size = self.path.stat().st_size
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {exc.strerror}") from None

    def rollback(self) -> None:
        """A checkpoint of the run failed (a full disk): the recording is cut back, when it is
        closed, to its last complete checkpoint, so that it holds the frames the summary
        reports, whole messages only (without the footer a closed file has: the viewer and a
        stream reader read it, ``rerun rrd verify`` does not)."""
        self._rolled_back = True

    def close(self) -> None:
        """Flush what is buffered and close the file (writes the footer)."""
        if self._closed:
            return
        if self._rolled_back:
            self._close_cut()
            return
        try:
            try:
                self.flush()
                # ids born in the run
                if self._has_truth and tuple(sorted(self._known_ids)) != self._blueprint_ids:
                    self.rec.send_blueprint(
                        blueprint(self.channels, sorted(self._known_ids), True)
                    )
            finally:
                self._closed = True
                try:
                    self.rec.flush(timeout_sec=10.0)
                finally:
                    disconnect_within(self.rec, DISCONNECT_TIMEOUT_S)
        except RuntimeError as exc:
            raise OutputError(f"cannot write {self.path}: {exc} (is the disk full?)") from None

    def _close_cut(self) -> None:
        """Close after a rollback: the frames after the last checkpoint are dropped and the file
        is cut back to that checkpoint's size (whatever the writer added after it, a message
        cut by the full disk or a footer, goes)."""
        self._closed = True
        self._buf, self._frames = defaultdict(list), []
        self._bytes = 0
        try:
            self.rec.flush(timeout_sec=10.0)
        except RuntimeError:
            pass
        finally:
            disconnect_within(self.rec, DISCONNECT_TIMEOUT_S)
        try:
            os.truncate(self.path, self._good_size)
        except OSError:
            pass

    def __enter__(self) -> RerunSink:
        return self

    def __exit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


DISCONNECT_TIMEOUT_S = 10.0
"""How long closing a recording may wait for the SDK's file writer (after its flush), s."""


def disconnect_within(rec: rr.RecordingStream, timeout_s: float) -> bool:
    """Disconnect ``rec`` on a thread of its own, waiting at most ``timeout_s``: True when it
    returned. The SDK's file writer can stay blocked on a full disk, and its ``disconnect`` with
    it (in compiled code, where no Python timeout reaches); then the recording is left to the
    process's exit, and the SDK's exit handler, which would wait for the same writer, is taken
    off (:func:`rerun.unregister_shutdown`)."""
    done = threading.Event()

    def run() -> None:
        try:
            rec.disconnect()
        finally:
            done.set()

    threading.Thread(target=run, name="rerun-disconnect", daemon=True).start()
    if done.wait(timeout_s):
        return True
    rr.unregister_shutdown()
    return False


def _drawn_thin(t) -> bool:
    """Occluded, tentative, and merged targets other than the merge's foreground get thin boxes."""
    if t.status == TargetStatus.MERGED:
        return t.diagnostics.get("role", 2.0) != 1.0
    return t.status.is_occluded or t.status == TargetStatus.TENTATIVE
