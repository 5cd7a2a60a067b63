"""``dualtrack detect SEQ --out DIR``: STDM detection on every frame, with its outputs and scores.

Writes ``det.txt``, ``rois.csv``, ``detections.rrd`` (``pipeline.sinks.detections``) and
``summary.json`` (frames, detections per frame, the detector's time per frame and ``fps``, and
apart from them ``background_seconds``, the time spent reading and estimating the sequence's
background, once per block of ``detection.background_window_frames``; with ground truth,
``recall`` and ``precision``: a target counts when it is visible (visibility >= 0.9 in a
synthetic scene's ``scene.json``, else any truth box) and no other target's or distractor's
box overlaps it, and it is found when an accepted ROI's centre lies inside its box; a ROI is
correct when its centre lies inside any target's box; one on a distractor of a random scene,
a moving object that is not a target, is not counted). The frames go through the run loop of
``pipeline.runloop``, as ``dualtrack track``'s do.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.config import config_to_dict, load_config
from pipeline.io.sequence import FramePair, open_sequence
from pipeline.stages.detection import Detections, detect, to_grey, warm_up

DETECT_FILES = ("det.txt", "rois.csv", "detections.rrd", "summary.json")


@dataclass
class DetectResult:
    out_dir: Path
    summary: dict[str, object]
    complete: bool = True
    interrupted: bool = False
    error: str | None = None


@dataclass(frozen=True)
class DetectItem:
    """One frame's detections, for the sinks."""

    detections: Detections
    image: np.ndarray
    stage_seconds: Mapping[str, float] = field(default_factory=dict)


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(
        a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]
    )


def score_frame(
    d: Detections, boxes: list[np.ndarray], visible: list[bool], distractors: list[np.ndarray] = ()
) -> tuple[int, int, int, int]:
    """(targets wanted, found, ROIs, correct ROIs) of one frame (see the module doc).

    A ROI whose centre lies in a distractor's box (a moving object that is not a target) and
    in no target's box is left out of the ROI count.
    """

    def inside(r, b):
        return b[0] <= r.centroid[0] <= b[0] + b[2] and b[1] <= r.centroid[1] <= b[1] + b[3]

    want = found = 0
    for k, b in enumerate(boxes):
        if (
            not visible[k]
            or any(_overlap(b, o) for j, o in enumerate(boxes) if j != k)
            or any(_overlap(b, o) for o in distractors)
        ):
            continue
        want += 1
        found += any(inside(r, b) for r in d.regions)
    on_target = [any(inside(r, b) for b in boxes) for r in d.regions]
    counted = sum(
        t or not any(inside(r, b) for b in distractors)
        for r, t in zip(d.regions, on_target, strict=True)
    )
    return want, found, counted, sum(on_target)


def _write_files(files, frames: FramePair, item: DetectItem) -> None:
    files.write(frames.index, item.detections)


def _recording_writer(channel: str):
    def write(rec, frames: FramePair, item: DetectItem) -> None:
        enc = getattr(frames, f"{channel}_encoded")
        rec.write(
            frames.index,
            (enc.data, enc.media_type) if enc is not None else None,
            item.image,
            item.detections,
        )

    return write


def run_detect(
    seq_path: str | Path,
    out: str | Path,
    sets: list[str] | None = None,
    config_path: Path | None = None,
    rrd: bool = True,
    force: bool = False,
    progress: bool | None = None,
    threads: bool = True,
    **open_kw: object,
) -> DetectResult:
    from pipeline.runloop import AdaptedSink, Job, run_job

    seq = open_sequence(seq_path, **open_kw)  # type: ignore[arg-type]
    cfg = load_config(config_path, sets or [])
    ch = (
        cfg.detect.detection.channel
        if cfg.detect.detection.channel in seq.channels
        else seq.channels[0]
    )
    out = Path(out)
    truth = seq.truth.primary() if seq.truth.has_truth else {}
    vis = seq.meta.get("visibility", {})
    vis = vis if isinstance(vis, dict) else {}
    counts = np.zeros(4, int)
    per_frame: list[int] = []
    det_s = [0.0, 0.0]  # wall, CPU (this thread's)

    from pipeline.io.background import camera_warning, sequence_background

    source = sequence_background(seq, ch, cfg.detect.detection)
    warm_up()  # the kernels loaded before the first timed frame
    background = [None]
    bg_s = [0.0]

    def step(fp: FramePair) -> DetectItem:
        img = getattr(fp, ch)
        if source is not None:
            tb = time.perf_counter()
            background[0] = source.at(fp.index)
            bg_s[0] += time.perf_counter() - tb
        t0, c0 = time.perf_counter(), time.thread_time()
        d = detect(
            to_grey(img),
            cfg.detect.detection,
            background[0],
            fp.visible if ch == "infrared" else None,
        )
        background[0] = d.background
        dt = time.perf_counter() - t0
        det_s[0] += dt
        det_s[1] += time.thread_time() - c0
        per_frame.append(len(d.regions))
        if truth:
            i = fp.index - 1
            ids = [g for g, b in truth.items() if not np.isnan(b[i]).any()]
            boxes = [truth[g][i] for g in ids]
            visible = [vis.get(str(g), [1.0] * seq.n_frames)[i] >= 0.9 for g in ids]
            others = [b[i] for b in seq.truth.distractors.values() if not np.isnan(b[i]).any()]
            counts[:] += score_frame(d, boxes, visible, others)
        return DetectItem(d, img, {"detection": dt})

    def make_sinks() -> list:
        from pipeline.sinks.detections import DetectionFiles, DetectionRecording

        sinks: list = [AdaptedSink(DetectionFiles(out), _write_files)]
        if rrd:
            rec = DetectionRecording(
                out / "detections.rrd", ch, seq.name, cfg.detect.detection.min_std
            )
            sinks.append(AdaptedSink(rec, _recording_writer(ch)))
        return sinks

    def finish(stats) -> dict[str, object]:
        n = stats.frames
        extra: dict[str, object] = {
            "detections_per_frame": float(np.mean(per_frame[:n])) if n else 0.0,
            "ms_per_frame": round(1e3 * det_s[0] / max(len(per_frame), 1), 3),
            # the detector's own work: what the reader and writer threads do meanwhile (and the
            # interpreter's lock they hold) is in the wall time, not here
            "ms_per_frame_cpu": round(1e3 * det_s[1] / max(len(per_frame), 1), 3),
            "fps": round(len(per_frame) / det_s[0], 1) if det_s[0] > 0 else None,
            "background_seconds": round(bg_s[0], 3),
        }
        if source is not None:
            extra["camera"] = cam = source.camera()
            line = camera_warning(cam, "det.txt holds them as found")
            if line:
                extra["warnings"] = [*summary.get("warnings", []), line]  # type: ignore[list-item]
        if truth:
            extra.update(
                {
                    "targets_scored": int(counts[0]),
                    "recall": float(counts[1] / counts[0]) if counts[0] else None,
                    "precision": float(counts[3] / counts[2]) if counts[2] else None,
                }
            )
        return extra

    summary: dict[str, object] = {
        "sequence": seq.name,
        "channel": ch,
        "frames": 0,
        "frames_total": seq.n_frames,
        "config": config_to_dict(cfg, "detect")["detect"]["detection"],
    }
    if seq.warnings:
        summary["warnings"] = list(seq.warnings)
    res = run_job(
        Job(
            f"detect {seq.name}",
            seq,
            out,
            DETECT_FILES,
            step,
            make_sinks,
            summary,
            finish,
            force=force,
            progress=progress,
            checkpoint_frames=cfg.rerun.batch_frames,
            checkpoint_min_seconds=cfg.rerun.checkpoint_min_seconds,
            threads=threads,
        )
    )
    return DetectResult(out, res.summary, res.complete, res.stats.interrupted, res.stats.error)
