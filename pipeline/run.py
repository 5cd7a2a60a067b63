"""Running a tracker over a sequence: reader -> engine -> sinks.

:func:`iter_track` is the bare loop (no files), :func:`track` collects its results, and
:func:`run_track` is ``dualtrack track``: it writes the run folder (``tracks.csv``,
``targets.csv``, ``run.rrd``, ``summary.json``, ``plots/``). A run stopped by Ctrl-C or
by a bad frame still closes every sink, so the CSVs and the .rrd are valid for the frames
done and ``summary.json`` says ``"complete": false``.
"""

from __future__ import annotations

import json
import shutil
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline import __version__
from pipeline.config import PipelineConfig, config_to_dict, load_config
from pipeline.errors import InputError
from pipeline.io.init import resolve_init
from pipeline.io.sequence import FramePair, Sequence, open_sequence
from pipeline.progress import Progress
from pipeline.trackers import DEFAULT_TRACKER, Engine, make_tracker
from pipeline.types import BBox, FrameResult, FrameTruth, InitTarget, TruthMatch

RUN_FILES = ("tracks.csv", "targets.csv", "run.rrd", "summary.json", "plots")


@dataclass
class TrackStep:
    """One iteration of :func:`iter_track`: the frames, the result and the seconds in the tracker."""

    frames: FramePair
    result: FrameResult
    tracker_seconds: float
    decode_seconds: float


def iter_track(seq: Sequence, engine: Engine, targets: list[InitTarget], stop: int | None = None) -> Iterator[TrackStep]:
    """Drive ``engine`` over ``seq``: ``start`` on frame 1, ``step`` on the others."""
    it = seq.frames(1, stop)
    while True:
        t0 = time.perf_counter()
        try:
            frames = next(it)
        except StopIteration:
            return
        t1 = time.perf_counter()
        result = engine.start(frames, targets) if frames.index == 1 else engine.step(frames)
        t2 = time.perf_counter()
        yield TrackStep(frames, result, t2 - t1, t1 - t0)


def track(
    sequence: Sequence | str | Path,
    tracker: str = DEFAULT_TRACKER,
    init: list[tuple[float, float, float, float]] | list[str] | None = None,
    config: PipelineConfig | None = None,
) -> list[FrameResult]:
    """Track a sequence in memory and return one :class:`FrameResult` per frame.

    ``init`` boxes are ``(x, y, w, h)`` tuples or ``"x,y,w,h"`` strings (ids 1..N); by
    default the sequence's own first-frame truth is used.
    """
    seq = sequence if isinstance(sequence, Sequence) else open_sequence(sequence)
    cfg = config or PipelineConfig()
    init_strs = [i if isinstance(i, str) else ",".join(map(str, i)) for i in init] if init else None
    targets = resolve_init(seq, init_strs)
    engine = make_tracker(tracker, cfg)
    return [s.result for s in iter_track(seq, engine, targets)]


@dataclass
class RunOptions:
    """Options of ``dualtrack track`` (see ``dualtrack track --help``)."""

    tracker: str = DEFAULT_TRACKER
    out_dir: Path | None = None
    init: list[str] | None = None
    init_file: Path | None = None
    detect: bool = False
    channel: str | None = None
    align: str = "none"
    gt_base: float | None = None
    config_path: Path | None = None
    sets: list[str] = field(default_factory=list)
    rrd: bool = True
    plots: bool = True
    protocol: str = "default"
    force: bool = False
    progress: bool | None = None
    stop_frame: int | None = None


@dataclass
class RunResult:
    out_dir: Path
    summary: dict[str, object]
    complete: bool
    interrupted: bool = False
    error: str | None = None
    boxes: dict[int, np.ndarray] = field(default_factory=dict)


def _prepare_out_dir(out: Path, force: bool) -> None:
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    if out.exists() and any(out.iterdir()):
        if not force:
            raise InputError(f"run folder {out} already exists and is not empty; pass --force to overwrite it")
        for name in RUN_FILES:
            p = out / name
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()
    out.mkdir(parents=True, exist_ok=True)


def _scene_seed(seq: Sequence) -> int | None:
    meta = seq.path / "scene.json"
    if meta.is_file():
        try:
            return int(json.loads(meta.read_text()).get("seed"))
        except (ValueError, TypeError, json.JSONDecodeError):
            return None
    return None


def frame_truth(seq: Sequence, result: FrameResult) -> FrameTruth:
    """The truth of this frame per channel, and each target's centre error, IoU and truth match against the
    scored channel's truth (ids as in the truth; a target that is not reported scores as a failure)."""
    i = result.frame - 1
    boxes = {ch: {tid: BBox(*b[i]) for tid, b in table.items() if not np.isnan(b[i]).any()}
             for ch, table in seq.truth.boxes.items()}
    scored = boxes.get(seq.truth.primary_channel() or "", {})
    err, iou, match = {}, {}, {}
    for t in result.targets:
        g = scored.get(t.id)
        if g is None:
            if t.id in seq.truth.primary():
                match[t.id] = TruthMatch.NO_TRUTH
            continue
        if t.status.is_reported:
            err[t.id] = float(np.hypot(t.box.cx - g.cx, t.box.cy - g.cy))
            iou[t.id] = t.box.iou(g)
        else:
            err[t.id], iou[t.id] = float("inf"), 0.0
        match[t.id] = TruthMatch.OVERLAP if iou[t.id] > 0 else TruthMatch.FAILURE
    return FrameTruth(boxes, err, iou, match)


def run_track(seq_path: str | Path, opts: RunOptions) -> RunResult:
    """``dualtrack track``: track a sequence folder and write its run folder."""
    from pipeline.eval import curves, evaluate
    from pipeline.io.results import TrackTable
    from pipeline.sinks.csv_sink import CsvSink
    from pipeline.sinks.summary import write_json

    seq = open_sequence(seq_path, channel=opts.channel, align=opts.align, gt_base=opts.gt_base)
    cfg = load_config(opts.config_path, opts.sets)
    engine = make_tracker(opts.tracker, cfg)
    from pipeline.trackers import NEEDS_NO_INIT, detect_init

    detected_ids = opts.tracker in NEEDS_NO_INIT or (opts.detect and not opts.init and opts.init_file is None)
    if opts.tracker in NEEDS_NO_INIT:
        targets = []
    elif detected_ids:
        targets = detect_init(seq, cfg)
    else:
        targets = resolve_init(seq, opts.init, opts.init_file, opts.channel)
    out = Path(opts.out_dir) if opts.out_dir is not None else Path("runs") / seq.name
    _prepare_out_dir(out, opts.force)

    n = seq.n_frames if opts.stop_frame is None else min(opts.stop_frame, seq.n_frames)
    summary: dict[str, object] = {
        "tracker": opts.tracker,
        "sequence": seq.name,
        "sequence_path": str(seq.path.resolve()),
        "layout": seq.layout,
        "channels": list(seq.channels),
        "frames": 0,
        "frames_total": seq.n_frames,
        "targets": [{"id": t.id, "box": list(t.box.as_tuple())} for t in targets],
        "ids": "detected" if detected_ids else "given",
        "config": config_to_dict(cfg),
        "version": __version__,
        "seed": _scene_seed(seq),
        "stage_seconds": {},
        "fps_tracking": None,
        "fps_end_to_end": None,
        "complete": False,
        "metrics": None,
    }
    write_json(out / "summary.json", summary)

    boxes: dict[int, np.ndarray] = {}
    stage: dict[str, float] = {}
    tracker_s = decode_s = sink_s = 0.0
    done = 0
    interrupted = False
    error: str | None = None
    if opts.rrd:  # importing rerun takes about 0.4 s: process start-up, not part of the run's time
        from pipeline.sinks.rerun_sink import RerunSink
    t_start = time.perf_counter()
    csv_sink = CsvSink(out)
    rrd_sink = None
    try:
        if opts.rrd:
            start = f"{opts.tracker} on {seq.name} ({seq.layout}, {'+'.join(seq.channels)}): " + ", ".join(
                f"T{t.id} {t.box}" for t in targets)
            rrd_sink = RerunSink(out / "run.rrd", seq.channels, [t.id for t in targets], cfg.rerun, seq.name,
                                 config_to_dict(cfg), seq.truth.has_truth, start)
        with Progress(n, f"{opts.tracker} {seq.name}", enabled=opts.progress) as bar, _sigint_at_frame_end() as sigint:
            for s in iter_track(seq, engine, targets, n):
                if sigint["count"]:
                    raise KeyboardInterrupt
                tracker_s += s.tracker_seconds
                decode_s += s.decode_seconds
                for k, v in s.result.stage_seconds.items():
                    stage[k] = stage.get(k, 0.0) + v
                ts = time.perf_counter()
                csv_sink.write(s.result)
                if rrd_sink is not None:
                    rrd_sink.write(s.frames, s.result, frame_truth(seq, s.result) if seq.truth.has_truth else None)
                sink_s += time.perf_counter() - ts
                for t in s.result.targets:
                    if t.id not in boxes:
                        boxes[t.id] = np.full((seq.n_frames, 4), np.nan)
                    if t.status.is_reported:
                        boxes[t.id][s.frames.index - 1] = t.box.as_tuple()
                done += 1
                bar.update(1, fps=f"{done / max(tracker_s, 1e-9):.0f}")
    except KeyboardInterrupt:
        interrupted = True
    except InputError as exc:
        error = str(exc)
    finally:
        ts = time.perf_counter()
        csv_sink.close()
        if rrd_sink is not None:
            rrd_sink.close()
        sink_s += time.perf_counter() - ts
    wall = time.perf_counter() - t_start

    complete = not interrupted and error is None and done == n
    stage.update({"decode": decode_s, "tracker": tracker_s, "sinks": sink_s})
    summary.update({
        "frames": done,
        "stage_seconds": {k: round(v, 6) for k, v in stage.items()},
        "fps_tracking": round(done / tracker_s, 3) if tracker_s > 0 else None,
        "fps_end_to_end": round(done / wall, 3) if wall > 0 else None,
        "complete": complete,
    })
    if error is not None:
        summary["error"] = error
    if interrupted:
        summary["interrupted"] = True
    if seq.truth.has_truth and done > 0:
        truth = _truncate(seq, done)
        table = TrackTable({k: v[:done] for k, v in boxes.items()}, {})
        id_rule = "assign" if detected_ids else "truth"  # detection-made ids are arbitrary
        summary["metrics"] = evaluate(truth, table, done, opts.protocol, id_rule)
        if opts.plots:
            from pipeline.sinks.plots import write_plots

            write_plots(out / "plots", curves(truth, table, done, id_rule), f"{seq.name} / {opts.tracker}")
    write_json(out / "summary.json", summary)
    return RunResult(out, summary, complete, interrupted, error, boxes)


@contextmanager
def _sigint_at_frame_end() -> Iterator[dict[str, int]]:
    """Ctrl-C is acted on between frames, so tracks.csv, targets.csv, the .rrd and summary.json always describe
    the same frames (a KeyboardInterrupt between two of a frame's writes left the CSV one row ahead of the
    summary). A second Ctrl-C interrupts at once. Outside the main thread signals are left alone."""
    state = {"count": 0}
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(signum: int, frame: object) -> None:
        state["count"] += 1
        if state["count"] > 1:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield state
    finally:
        signal.signal(signal.SIGINT, previous)


def _truncate(seq: Sequence, n: int):
    from pipeline.io.sequence import Truth

    t = seq.truth
    return Truth(
        {c: {i: b[:n] for i, b in d.items()} for c, d in t.boxes.items()},
        {i: v[:n] for i, v in t.visibility.items()},
        t.files,
        t.multi,
    )
