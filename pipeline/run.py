"""Running a tracker over a sequence: reader -> engine -> sinks.

:func:`iter_track` is the bare loop (no files), :func:`track` collects its results, and
:func:`run_track` is ``dualtrack track``: it writes the run folder (``tracks.csv``,
``targets.csv``, ``run.rrd``, ``summary.json``, ``plots/``) through the run loop of
``pipeline.runloop``, which decodes, tracks and writes at once and keeps every output valid
after any fault (a run stopped by a signal or a bad frame says ``"complete": false``).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline._version import __version__
from pipeline.config import PipelineConfig, config_to_dict, load_config
from pipeline.errors import InputError
from pipeline.io.background import camera_warning
from pipeline.io.frames import ImageListSource
from pipeline.io.init import resolve_init
from pipeline.io.sequence import FramePair, Sequence, open_sequence
from pipeline.trackers import DEFAULT_TRACKER, Engine, make_tracker
from pipeline.trackers.base import attach_sequence
from pipeline.types import BBox, FrameResult, FrameTruth, InitTarget, zoomed

RUN_FILES = ("tracks.csv", "targets.csv", "run.rrd", "summary.json", "plots")


@dataclass
class TrackStep:
    """One iteration of :func:`iter_track`: the frames, the result and the seconds in the
    tracker."""

    frames: FramePair
    result: FrameResult
    tracker_seconds: float
    decode_seconds: float


def iter_track(
    seq: Sequence, engine: Engine, targets: list[InitTarget], stop: int | None = None
) -> Iterator[TrackStep]:
    """Drive ``engine`` over ``seq``: ``start`` on frame 1, ``step`` on the others; on a sequence
    read smaller (:meth:`Sequence.decode_at`) the targets and results stay in the source's px."""
    started = _at_scale(targets, seq.scale)
    it = seq.frames(1, stop)
    while True:
        t0 = time.perf_counter()
        try:
            frames = next(it)
        except StopIteration:
            return
        t1 = time.perf_counter()
        result = _engine_step(engine, frames, started, seq.scale)
        yield TrackStep(frames, result, time.perf_counter() - t1, t1 - t0)


def _engine_step(
    engine: Engine, frames: FramePair, started: list[InitTarget], scale: int
) -> FrameResult:
    """One frame of ``engine`` (``start`` with ``started``, in the px of the frames as read, on
    frame 1; ``step`` after), its result in the source's px."""
    result = engine.start(frames, started) if frames.index == 1 else engine.step(frames)
    return zoomed(result, scale)


def _at_scale(targets: list[InitTarget], scale: int) -> list[InitTarget]:
    """``targets`` (source px) in the px of frames read at ``1 / scale``."""
    if scale == 1:
        return targets
    return [InitTarget(t.id, t.box.times(1 / scale)) for t in targets]


def track(
    sequence: Sequence | str | Path,
    tracker: str = DEFAULT_TRACKER,
    init: list[BBox] | list[tuple[float, float, float, float]] | list[str] | None = None,
    config: PipelineConfig | None = None,
) -> list[FrameResult]:
    """Track a sequence in memory and return one :class:`FrameResult` per frame.

    Parameters
    ----------
    sequence : Sequence or path
        An opened sequence or a sequence folder of any supported layout.
    tracker : str
        An engine of ``dualtrack trackers``; default ``dual``.
    init : list of BBox, ``(x, y, w, h)`` or ``"x,y,w,h"``, optional
        The targets' boxes in frame 1 (ids 1..N); default the sequence's own first-frame truth.
    config : PipelineConfig, optional
        Every tracker's parameters; default ``PipelineConfig()``.

    Returns
    -------
    list of FrameResult
        One per frame: every target's box, status, decision and diagnostics, the frame's
        events and the seconds per stage.

    Examples
    --------
    >>> import tempfile
    >>> from pipeline import BBox, PipelineConfig, synthesize_random, track
    >>> folder = synthesize_random(tempfile.mkdtemp() + "/scene", seed=3, targets=1, frames=30,
    ...                            progress=False)
    >>> results = track(folder, config=PipelineConfig())  # from the scene's first-frame truth
    >>> len(results), results[-1].targets[0].status.value
    (30, 'tracking')
    >>> first = BBox(*results[0].targets[0].box.as_tuple())
    >>> again = track(folder, tracker="meanshift", init=[first])
    >>> again[0].targets[0].box == results[0].targets[0].box
    True
    """
    seq = sequence if isinstance(sequence, Sequence) else open_sequence(sequence)
    cfg = config or PipelineConfig()
    targets = resolve_init(seq, list(init) if init else None)
    engine = make_tracker(tracker, cfg)
    attach_sequence(engine, seq)
    return [s.result for s in iter_track(seq, engine, targets)]


@dataclass
class RunOptions:
    """Options of ``dualtrack track`` (see ``dualtrack track --help``).

    Parameters
    ----------
    tracker : str
        An engine of ``dualtrack trackers``; default ``dual``.
    out_dir : Path, optional
        The run folder; default ``runs/<sequence name>``.
    init : list of str, optional
        ``"x,y,w,h"`` boxes of frame 1 (0-based px; ids 1..N), as ``--init``.
    init_file : Path, optional
        A file of initial boxes (``--init-file``).
    detect : bool
        Find the initial targets with the detector (``--detect``).
    channel : {"visible", "infrared"}, optional
        What a one-channel folder holds, or the one channel of a two-channel folder to use.
    align : {"none", "resize"}
        Scale infrared frames to the visible size when they differ.
    gt_base : float, optional
        The ground truth's coordinate base (0 or 1), overriding the layout's.
    config_path : Path, optional
        A TOML configuration file (``--config``).
    sets : list of str
        ``path.param=value`` items (``--set``), applied after the file.
    rrd, plots : bool
        Write the recording and the plots; default True.
    protocol : str
        The evaluation protocol of ``summary.json``'s metrics; default ``default``.
    force : bool
        Overwrite a non-empty run folder (only the files a run writes).
    progress : bool, optional
        A progress bar (default: on a terminal only).
    stop_frame : int, optional
        Stop after this frame (``--frames``).
    config : PipelineConfig, optional
        A resolved configuration instead of ``config_path`` and ``sets``.
    threads : bool
        Decode and write on threads beside the tracker (default); False does all three in
        turn on one thread, with the same results.
    decode_scale : int, optional
        Track on frames read at ``1 / decode_scale`` of their size (1, 2, 4 or 8; JPEG files
        decoded there by libjpeg's DCT scaling), the boxes written at full size; None (default,
        ``--decode-scale auto``): :func:`auto_decode_scale`. Only for trackers started from
        given boxes.

    Examples
    --------
    >>> opts = RunOptions(tracker="meanshift", sets=["meanshift.search.max_iterations=30"])
    >>> opts.tracker, opts.rrd
    ('meanshift', True)
    """

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
    config: PipelineConfig | None = None
    threads: bool = True
    decode_scale: int | None = None


@dataclass
class RunResult:
    """What :func:`run_track` did: the run folder, ``summary.json``'s content, whether every
    frame was done, and each target's boxes (frame-indexed, NaN where it was not reported)."""

    out_dir: Path
    summary: dict[str, object]
    complete: bool
    interrupted: bool = False
    error: str | None = None
    boxes: dict[int, np.ndarray] = field(default_factory=dict)
    crash: BaseException | None = (
        None  # the exception behind an internal error (DUALTRACK_DEBUG re-raises it)
    )


@dataclass(frozen=True)
class TrackItem:
    """What the track sinks get per frame: the tracker's result and, with truth, how it scores."""

    result: FrameResult
    truth: FrameTruth | None

    @property
    def stage_seconds(self) -> Mapping[str, float]:
        return self.result.stage_seconds


def _write_csv(sink, frames: FramePair, item: TrackItem) -> None:
    sink.write(item.result)


def _write_rrd(sink, frames: FramePair, item: TrackItem) -> None:
    sink.write(frames, item.result, item.truth)


AUTO_MIN_TARGET_PX = 32
"""``--decode-scale auto`` reads frames smaller only while every initial target's shorter side
stays at least this many px there (the filter's template and the level set's region still hold
the target's shape)."""

AUTO_MIN_FRAME_PX = 360
"""... and the frame's shorter side at least this many px."""


def auto_decode_scale(seq: Sequence, targets: list[InitTarget]) -> int:
    """The decode scale of ``--decode-scale auto``: the largest of 8, 4 and 2 at which every
    initial target's shorter side is still :data:`AUTO_MIN_TARGET_PX` px and the frame's
    :data:`AUTO_MIN_FRAME_PX`, for sequences of JPEG files (where libjpeg decodes at that size
    for less); 1 otherwise (no targets, other formats, small frames or targets).

    A 1920 x 1080 JPEG sequence with a 67 x 80 px target is read at half its size; a 320 x 240
    one, or a 1080p one with a 40 px target, whole."""
    if not targets or not all(
        isinstance(s, ImageListSource)
        and all(p.suffix.lower() in (".jpg", ".jpeg") for p in s.paths)
        for s in seq.sources.values()
    ):
        return 1
    side = min(min(t.box.w, t.box.h) for t in targets)
    frame = min(seq.width, seq.height)
    for f in (8, 4, 2):
        if side / f >= AUTO_MIN_TARGET_PX and frame / f >= AUTO_MIN_FRAME_PX:
            return f
    return 1


def run_track(
    seq_path: str | Path,
    opts: RunOptions | None = None,
    *,
    config: PipelineConfig | None = None,
    **options: object,
) -> RunResult:
    """``dualtrack track``: track a sequence folder and write its run folder (through
    ``pipeline.runloop``).

    Parameters
    ----------
    seq_path : path
        The sequence folder.
    opts : RunOptions, optional
        The options of ``dualtrack track``; or give them as keywords (``out_dir=...,
        tracker=...``).
    config : PipelineConfig, optional
        Every tracker's parameters (instead of ``RunOptions.config_path`` / ``sets``).

    Returns
    -------
    RunResult
        The run folder, ``summary.json``'s content (``complete`` false for a run stopped by a
        signal or a bad frame, ``error`` saying why), and each target's boxes.

    Raises
    ------
    InputError
        Bad input before the first frame: no such folder, no initial target, a bad option or
        configuration, a run folder that is not empty without ``force``.

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> from pipeline import PipelineConfig, run_track, synthesize_random
    >>> root = Path(tempfile.mkdtemp())
    >>> scene = synthesize_random(root / "scene", seed=3, targets=1, frames=30, progress=False)
    >>> res = run_track(scene, out_dir=root / "run", config=PipelineConfig(), rrd=False,
    ...                 plots=False, progress=False)
    >>> res.complete, sorted(p.name for p in res.out_dir.iterdir())
    (True, ['summary.json', 'targets.csv', 'tracks.csv'])
    >>> json.loads((res.out_dir / "summary.json").read_text())["frames"]
    30
    """
    if opts is None:
        opts = RunOptions(**options)  # type: ignore[arg-type]
    elif options:
        raise InputError(f"give either opts or keyword options, not both: {', '.join(options)}")
    if config is not None:
        from dataclasses import replace

        opts = replace(opts, config=config)
    from pipeline.eval import Assessment, frame_truth
    from pipeline.io.results import TrackTable
    from pipeline.runloop import AdaptedSink, Job, run_job

    if opts.stop_frame is not None and opts.stop_frame < 1:
        raise InputError(f"--frames must be at least 1; got {opts.stop_frame}")
    seq = open_sequence(seq_path, channel=opts.channel, align=opts.align, gt_base=opts.gt_base)
    cfg = opts.config if opts.config is not None else load_config(opts.config_path, opts.sets)
    engine = make_tracker(opts.tracker, cfg)
    from pipeline.trackers import NEEDS_NO_INIT, detect_init

    detected_ids = opts.tracker in NEEDS_NO_INIT or (
        opts.detect and not opts.init and opts.init_file is None
    )
    if opts.tracker in NEEDS_NO_INIT:
        targets = []
    elif detected_ids:
        targets = detect_init(seq, cfg.detect)
    else:
        targets = resolve_init(seq, opts.init, opts.init_file, opts.channel)
    if detected_ids and opts.decode_scale not in (None, 1):
        raise InputError(
            "--decode-scale applies to trackers started from given boxes, not to detected ones"
        )
    scale = 1 if detected_ids else (opts.decode_scale or auto_decode_scale(seq, targets))
    if scale not in (1, 2, 4, 8):
        raise InputError(f"--decode-scale must be auto, 1, 2, 4 or 8; got {scale}")
    seq.decode_at(scale)
    attach_sequence(engine, seq)  # after decode_at: the engine's background reads frames too
    started = _at_scale(targets, scale)
    out = Path(opts.out_dir) if opts.out_dir is not None else Path("runs") / seq.name
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
        "decode_scale": scale,
        "config": config_to_dict(cfg, opts.tracker),
        "version": __version__,
        "seed": seq.meta.get("seed") if isinstance(seq.meta.get("seed"), int) else None,
        "stage_seconds": {},
        "fps_tracking": None,
        "fps_tracking_cpu": None,
        "fps_end_to_end": None,
        "complete": False,
        "metrics": None,
    }
    if seq.warnings:
        summary["warnings"] = list(seq.warnings)
    if opts.rrd:  # importing rerun takes about 0.4 s: process start-up, not part of the run's time
        from pipeline.sinks.rerun_sink import RerunSink

    boxes: dict[int, np.ndarray] = {}
    has_truth = seq.truth.has_truth

    def step(frames: FramePair) -> TrackItem:
        result = _engine_step(engine, frames, started, scale)
        for t in result.targets:
            if t.id not in boxes:
                boxes[t.id] = np.full((seq.n_frames, 4), np.nan)
            if t.status.is_reported:
                boxes[t.id][frames.index - 1] = t.box.as_tuple()
        return TrackItem(result, frame_truth(seq.truth, result) if has_truth else None)

    def make_sinks() -> list:
        from pipeline.sinks.csv_sink import CsvSink

        sinks: list = [AdaptedSink(CsvSink(out), _write_csv)]
        if opts.rrd:
            start = (
                f"{opts.tracker} on {seq.name} ({seq.layout}, {'+'.join(seq.channels)}): "
                + ", ".join(f"T{t.id} {t.box}" for t in targets)
                + (f"; tracked on frames read at 1/{scale} of their size" if scale > 1 else "")
            )
            try:
                rrd = RerunSink(
                    out / "run.rrd",
                    seq.channels,
                    [t.id for t in targets],
                    cfg.rerun,
                    seq.name,
                    config_to_dict(cfg, opts.tracker),
                    has_truth,
                    start,
                )
            except BaseException:
                sinks[0].close()
                raise
            sinks.append(AdaptedSink(rrd, _write_rrd))
        return sinks

    def finish(stats) -> dict[str, object]:
        extra: dict[str, object] = {}
        rule = getattr(getattr(engine, "core", None), "on_moving_camera", None)
        camera = engine.camera() if rule and hasattr(engine, "camera") else None
        if camera is not None:
            extra["camera"] = camera
            line = camera_warning(camera, rule)
            if line:
                extra["warnings"] = [*summary.get("warnings", []), line]  # type: ignore[list-item]
        if not has_truth:
            return extra
        done = stats.frames
        truth = seq.truth.truncated(done)
        table = TrackTable({k: v[:done] for k, v in boxes.items()}, {})
        id_rule = "assign" if detected_ids else "truth"  # detection-made ids are arbitrary
        assessment = Assessment(truth, table, done, id_rule)  # the run's one evaluation
        extra["metrics"] = assessment.metrics(opts.protocol)
        if opts.plots:
            from pipeline.sinks.plots import write_plots

            title = f"{seq.name} / {opts.tracker}"
            write_plots(out / "plots", assessment.curves(), title)
        return extra

    job = Job(
        f"{opts.tracker} {seq.name}",
        seq,
        out,
        RUN_FILES,
        step,
        make_sinks,
        summary,
        finish,
        stop_frame=opts.stop_frame,
        force=opts.force,
        progress=opts.progress,
        checkpoint_frames=cfg.rerun.batch_frames,
        checkpoint_min_seconds=cfg.rerun.checkpoint_min_seconds,
        threads=opts.threads,
    )
    res = run_job(job)
    st = res.stats
    return RunResult(out, res.summary, res.complete, st.interrupted, st.error, boxes, st.crash)
