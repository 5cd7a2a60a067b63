"""OpenCV's trackers behind the dualtrack interface: ``camshift``, ``mil``, ``csrt``, ``kcf``.

They are the peers people use today and the baseline every dualtrack tracker is compared
with. Each runs on one channel: visible when the sequence has it, else infrared (as
docs/formats.md asks of single-channel folders). CSRT and KCF live in OpenCV's contrib
modules; where the installed OpenCV lacks them, asking for them is a clear error.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import cv2
import numpy as np

from pipeline.errors import InputError
from pipeline.io.sequence import FramePair
from pipeline.tracker_config import CamShiftConfig, OpenCVTrackerConfig
from pipeline.trackers.base import pick_channel
from pipeline.trackers.lifecycle import transition
from pipeline.types import (
    BBox,
    FrameResult,
    InitTarget,
    TargetResult,
    TargetStatus,
)


def _channel_image(frames: FramePair, channel: str) -> np.ndarray:
    img = getattr(frames, channel)
    assert img is not None
    return img


class CamShiftEngine:
    """OpenCV CamShift on a hue (visible) or intensity (infrared) back-projection."""

    name = "camshift"

    def __init__(self, cfg: CamShiftConfig, channel: str = "visible"):
        self.cfg = cfg
        self.preferred = channel
        self.channel = channel
        self.targets: dict[int, tuple[np.ndarray, tuple[int, int, int, int], TargetStatus]] = {}

    def _prob_input(
        self, frames: FramePair
    ) -> tuple[np.ndarray, np.ndarray | None, list[int], list[int], list[float]]:
        img = _channel_image(frames, self.channel)
        if self.channel == "visible":
            hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
            mask = cv2.inRange(
                hsv, (0, self.cfg.min_saturation, self.cfg.min_value), (180, 255, 255)
            )
            return hsv, mask, [0], [self.cfg.hue_bins], [0, 180]
        return img, None, [0], [self.cfg.intensity_bins], [0, 256]

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult:
        self.channel = pick_channel(frames, self.preferred)
        t0 = time.perf_counter()
        src, mask, chans, bins, ranges = self._prob_input(frames)
        h, w = frames.shape
        out = []
        for t in targets:
            x, y, bw, bh = t.box.to_cv(w, h)
            roi_mask = np.zeros((h, w), np.uint8)
            roi_mask[y : y + bh, x : x + bw] = 255
            if mask is not None:
                roi_mask = cv2.bitwise_and(roi_mask, mask)
            hist = cv2.calcHist([src], chans, roi_mask, bins, ranges)
            cv2.normalize(hist, hist, 0, 255, cv2.NORM_MINMAX)
            self.targets[t.id] = (hist, (x, y, bw, bh), TargetStatus.TRACKING)
            out.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init"))
        return FrameResult(frames.index, tuple(out), (), {"camshift": time.perf_counter() - t0})

    def step(self, frames: FramePair) -> FrameResult:
        t0 = time.perf_counter()
        src, mask, chans, _bins, ranges = self._prob_input(frames)
        h, w = frames.shape
        crit = (
            cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT,
            self.cfg.max_iterations,
            self.cfg.epsilon_px,
        )
        out, events = [], []
        for tid, (hist, window, status) in self.targets.items():
            prob = cv2.calcBackProject([src], chans, hist, ranges, 1)
            if mask is not None:
                prob &= mask
            rot, new_window = cv2.CamShift(prob, window, crit)
            (cx, cy), (rw, rh), _ang = rot
            if rw <= 1 or rh <= 1 or not np.isfinite([cx, cy, rw, rh]).all():
                new_status = TargetStatus.OCCLUDED_SEVERE
                box = BBox(*window)
                keep = window
            else:
                bx, by, bw, bh = cv2.boundingRect(cv2.boxPoints(rot).astype(np.float32))
                box = BBox(float(bx), float(by), float(bw), float(bh)).clip(w, h)
                if box.w < 1 or box.h < 1:
                    box = BBox(*window)
                new_status = TargetStatus.TRACKING
                keep = BBox(*new_window).to_cv(w, h)
            if new_status != status:
                why = "CamShift window collapsed" if new_status.is_occluded else "CamShift window"
                events += transition(tid, status, new_status, why)
            self.targets[tid] = (hist, keep, new_status)
            out.append(
                TargetResult(
                    tid,
                    box,
                    new_status,
                    "camshift",
                    confidence=0.3 if new_status.is_occluded else 1.0,
                )
            )
        return FrameResult(
            frames.index, tuple(out), tuple(events), {"camshift": time.perf_counter() - t0}
        )


def _factory(name: str) -> Callable[[], object] | None:
    """Constructor of OpenCV tracker ``name`` ('MIL', 'CSRT', 'KCF'), wherever this OpenCV has
    it."""
    cls = getattr(cv2, f"Tracker{name}", None)
    if cls is not None and hasattr(cls, "create"):
        return cls.create
    fn = getattr(cv2, f"Tracker{name}_create", None)
    if fn is not None:
        return fn
    legacy = getattr(cv2, "legacy", None)
    if legacy is not None:
        fn = getattr(legacy, f"Tracker{name}_create", None)
        if fn is not None:
            return fn
    return None


def opencv_tracker_available(name: str) -> bool:
    return _factory(name.upper()) is not None


class OpenCVEngine:
    """One OpenCV ``Tracker`` object per target (MIL, CSRT or KCF)."""

    def __init__(self, kind: str, cfg: OpenCVTrackerConfig):
        factory = _factory(kind.upper())
        if factory is None:
            raise InputError(
                f"tracker {kind!r} needs OpenCV's contrib modules, which this OpenCV "
                f"({cv2.__version__}, headless) lacks; install opencv-contrib-python-headless "
                "in a separate virtual environment to run it"
            )
        self.name = kind
        self.kind = kind
        self._factory = factory
        self.cfg = cfg
        self.channel = cfg.channel
        self.trackers: dict[int, tuple[object, BBox, TargetStatus]] = {}

    def _image(self, frames: FramePair) -> np.ndarray:
        img = _channel_image(frames, self.channel)
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult:
        self.channel = pick_channel(frames, self.cfg.channel)
        t0 = time.perf_counter()
        img = self._image(frames)
        h, w = frames.shape
        out = []
        for t in targets:
            tr = self._factory()
            tr.init(img, t.box.to_cv(w, h))  # type: ignore[attr-defined]
            self.trackers[t.id] = (tr, t.box, TargetStatus.TRACKING)
            out.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init"))
        return FrameResult(frames.index, tuple(out), (), {self.kind: time.perf_counter() - t0})

    def step(self, frames: FramePair) -> FrameResult:
        t0 = time.perf_counter()
        img = self._image(frames)
        out, events = [], []
        for tid, (tr, last, status) in self.trackers.items():
            ok, rect = tr.update(img)  # type: ignore[attr-defined]
            if ok and rect[2] > 0 and rect[3] > 0:
                box, new_status = BBox(*map(float, rect)), TargetStatus.TRACKING
            else:
                box, new_status = last, TargetStatus.LOST
            if new_status != status:
                why = (
                    "reported the target"
                    if new_status == TargetStatus.TRACKING
                    else "reported failure"
                )
                events += transition(tid, status, new_status, f"{self.kind} {why}")
            self.trackers[tid] = (tr, box, new_status)
            out.append(TargetResult(tid, box, new_status, f"opencv-{self.kind}"))
        return FrameResult(
            frames.index, tuple(out), tuple(events), {self.kind: time.perf_counter() - t0}
        )
