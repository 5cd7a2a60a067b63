"""``dualtrack detect SEQ --out DIR``: STDM detection on every frame, with its outputs and scores.

Writes ``det.txt``, ``rois.csv``, ``detections.rrd`` (``pipeline.sinks.detections``) and
``summary.json`` (frames, detections per frame, stage time, ``fps``; with ground truth,
``recall`` and ``precision``: a target counts when it is visible (visibility >= 0.9 in a
synthetic scene's ``scene.json``, else any truth box) and no other target's box overlaps
it, and it is found when an accepted ROI's centre lies inside its box; a ROI is correct when
its centre lies inside any target's box).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.config import config_to_dict, load_config
from pipeline.errors import InputError
from pipeline.io.sequence import open_sequence
from pipeline.progress import Progress
from pipeline.stages.detection import Detections, detect, to_grey


@dataclass
class DetectResult:
    out_dir: Path
    summary: dict[str, object]


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3])


def score_frame(d: Detections, boxes: list[np.ndarray], visible: list[bool]) -> tuple[int, int, int, int]:
    """(targets wanted, found, ROIs, correct ROIs) of one frame (see the module doc)."""
    def inside(r, b):
        return b[0] <= r.centroid[0] <= b[0] + b[2] and b[1] <= r.centroid[1] <= b[1] + b[3]

    want = found = 0
    for k, b in enumerate(boxes):
        if not visible[k] or any(_overlap(b, o) for j, o in enumerate(boxes) if j != k):
            continue
        want += 1
        found += any(inside(r, b) for r in d.regions)
    correct = sum(any(inside(r, b) for b in boxes) for r in d.regions)
    return want, found, len(d.regions), correct


def run_detect(seq_path: str | Path, out: str | Path, sets: list[str] | None = None, config_path: Path | None = None,
               rrd: bool = True, force: bool = False, progress: bool | None = None, **open_kw: object) -> DetectResult:
    from pipeline.sinks.detections import DetectionFiles, DetectionRecording
    from pipeline.sinks.summary import write_json

    seq = open_sequence(seq_path, **open_kw)  # type: ignore[arg-type]
    cfg = load_config(config_path, sets or [])
    ch = cfg.detection.channel if cfg.detection.channel in seq.channels else seq.channels[0]
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not force:
        raise InputError(f"{out} already exists and is not empty; pass --force to overwrite it")
    out.mkdir(parents=True, exist_ok=True)
    truth = seq.truth.primary() if seq.truth.has_truth else {}
    vis: dict[str, list[float]] = {}
    meta = seq.path / "scene.json"
    if meta.is_file():
        vis = json.loads(meta.read_text()).get("visibility", {})
    files = DetectionFiles(out)
    rec = DetectionRecording(out / "detections.rrd", ch, seq.name, cfg.detection.min_std) if rrd else None
    counts = np.zeros(4, int)
    per_frame: list[int] = []
    det_s = 0.0
    error = None
    interrupted = False
    try:
        with Progress(seq.n_frames, f"detect {seq.name}", enabled=progress) as bar:
            for fp in seq.frames():
                img = getattr(fp, ch)
                t0 = time.perf_counter()
                d = detect(to_grey(img), cfg.detection)
                det_s += time.perf_counter() - t0
                files.write(fp.index, d)
                if rec is not None:
                    enc = getattr(fp, f"{ch}_encoded")
                    rec.write(fp.index, (enc.data, enc.media_type) if enc is not None else None, img, d)
                per_frame.append(len(d.regions))
                if truth:
                    i = fp.index - 1
                    ids = [g for g, b in truth.items() if not np.isnan(b[i]).any()]
                    boxes = [truth[g][i] for g in ids]
                    visible = [vis.get(str(g), [1.0] * seq.n_frames)[i] >= 0.9 for g in ids]
                    counts += score_frame(d, boxes, visible)
                bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    except InputError as e:
        error = str(e)
    finally:
        files.close()
        if rec is not None:
            rec.close()
    n = len(per_frame)
    summary: dict[str, object] = {
        "sequence": seq.name, "channel": ch, "frames": n, "frames_total": seq.n_frames,
        "complete": n == seq.n_frames and error is None and not interrupted,
        "detections_per_frame": float(np.mean(per_frame)) if per_frame else 0.0,
        "ms_per_frame": round(1e3 * det_s / max(n, 1), 3), "fps": round(n / det_s, 1) if det_s > 0 else None,
        "config": config_to_dict(cfg)["detection"],
    }
    if truth and n:
        summary.update({"targets_scored": int(counts[0]),
                        "recall": float(counts[1] / counts[0]) if counts[0] else None,
                        "precision": float(counts[3] / counts[2]) if counts[2] else None})
    if error:
        summary["error"] = error
    write_json(out / "summary.json", summary)
    if error:
        raise InputError(f"{error} (detections for the {n} frames before it are in {out})")
    if interrupted:
        raise KeyboardInterrupt
    return DetectResult(out, summary)
