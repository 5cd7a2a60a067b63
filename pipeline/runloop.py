"""One run loop for every command that walks a sequence (``track``, ``detect``, ``bench`` and the
batch's children).

The loop owns what those commands share; a command differs only in its *step* (the
tracker or the detector, called once per frame pair on the calling thread) and its *sinks*
(the files it writes):

* the run folder: refused when it holds files unless ``force``, which deletes only the
  files the command writes; an OS problem (read-only, under a file) is one clear line;
* the overlap of the work: a reader thread decodes frame pairs ahead into a bounded queue
  (OpenCV's decoders release the GIL), the step runs on the calling thread, and a writer
  thread feeds the sinks, so decoding, tracking and writing proceed at the same time; the
  results are the same as one thread doing all three in turn (``threads=False``);
* checkpoints: every ``checkpoint_frames`` frames, once ``checkpoint_min_seconds`` have passed
  since the last one, the sinks write what they hold in whole rows
  (``pipeline.sinks.rowfile``) and ``summary.json`` is replaced atomically with the number of
  frames on disk, so even after a SIGKILL the summary says how many frames the CSV files hold
  (a killed run's ``.rrd`` lacks its footer: ``rerun rrd verify`` refuses it, but the viewer
  and a stream reader read every frame up to that checkpoint);
* faults: an unreadable frame, a full disk or any error in a sink ends the run with one
  message that names the frame and the file, after every sink was closed, so the outputs
  stay valid for the frames done and ``summary.json`` says ``"complete": false``;
* signals: SIGINT (Ctrl-C) and SIGTERM alike stop the run between two frames; further
  signals while the sinks close and ``summary.json`` is written are held until it is.
"""

from __future__ import annotations

import queue
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from pipeline.errors import InputError, OutputError, describe_os_error
from pipeline.io.sequence import FramePair, Sequence
from pipeline.progress import Progress

_END = object()


class Sink(Protocol):
    """What the writer thread feeds: one ``write`` per frame in order, ``checkpoint`` to make it
    durable."""

    def write(self, frames: FramePair, item: object) -> None: ...

    def checkpoint(self) -> None: ...

    def close(self) -> None: ...


class AdaptedSink:
    """A :class:`Sink` over a file writer: ``write(frames, item)`` calls ``write_item(inner,
    frames, item)``; ``checkpoint``, ``close`` and (where the writer has it) ``rollback`` go to the
    writer."""

    def __init__(self, inner: object, write_item: Callable[[Any, FramePair, Any], None]):
        self.inner = inner
        self._write_item = write_item
        if hasattr(inner, "rollback"):
            self.rollback = inner.rollback

    def write(self, frames: FramePair, item: object) -> None:
        self._write_item(self.inner, frames, item)

    def checkpoint(self) -> None:
        self.inner.checkpoint()  # type: ignore[attr-defined]

    def close(self) -> None:
        self.inner.close()  # type: ignore[attr-defined]


@dataclass
class LoopStats:
    """What a run did: frames on disk, seconds per part, how it ended."""

    frames: int = 0
    tracker_s: float = 0.0
    tracker_cpu_s: float = 0.0  # CPU seconds of the calling thread inside the step
    decode_s: float = 0.0  # the reader's wait for decoded pairs (two decoders: under their work)
    sinks_s: float = 0.0
    wall_s: float = 0.0
    stage_s: dict[str, float] = field(default_factory=dict)
    interrupted: bool = False
    error: str | None = None
    crash: BaseException | None = (
        None  # the unexpected exception behind an internal error, for debugging
    )


@dataclass
class Job:
    """One run of a command over a sequence (see the module doc).

    ``step(frames)`` returns the item the sinks get (its ``stage_seconds`` mapping, when it
    has one, is summed per stage); ``make_sinks()`` builds the sinks once the run folder is
    ready; ``summary`` is the base of ``summary.json``; ``finish(stats)`` returns the fields
    added at the end (metrics, plots), called only when some frames were done.
    """

    label: str
    seq: Sequence
    out_dir: Path
    files: tuple[str, ...]
    step: Callable[[FramePair], object]
    make_sinks: Callable[[], list[Sink]]
    summary: dict[str, object]
    finish: Callable[[LoopStats], dict[str, object]] | None = None
    stop_frame: int | None = None
    force: bool = False
    progress: bool | None = None
    checkpoint_frames: int = 16
    checkpoint_min_seconds: float = 0.0
    threads: bool = True


@dataclass
class LoopResult:
    out_dir: Path
    summary: dict[str, object]
    stats: LoopStats

    @property
    def complete(self) -> bool:
        return bool(self.summary.get("complete"))


def prepare_out_dir(out: Path, force: bool, files: tuple[str, ...]) -> None:
    """Make the run folder: refuse a non-empty one unless ``force`` (then delete only
    ``files``)."""
    import shutil

    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} exists and is not a folder")
    try:
        if out.exists() and any(out.iterdir()):
            if not force:
                raise InputError(
                    f"run folder {out} already exists and is not empty; pass --force to "
                    "overwrite it"
                )
            for name in files:
                p = out / name
                if p.is_dir():
                    shutil.rmtree(p)
                elif p.exists() or p.is_symlink():
                    p.unlink()
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".dualtrack-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except (NotADirectoryError, FileExistsError):
        raise OutputError(f"--out {out}: a part of the path is a file, not a folder") from None
    except OSError as exc:
        raise OutputError(
            f"cannot write the run folder {describe_os_error(exc, str(out))}"
        ) from None


class _Reader:
    """Decodes frame pairs ahead of the step into a bounded queue (or inline without threads)."""

    def __init__(self, seq: Sequence, stop: int | None, threaded: bool, depth: int = 8):
        self.seq, self.stop_frame, self.threaded = seq, stop, threaded
        self.decode_s = 0.0
        self._stop = threading.Event()
        if threaded:
            self._q: queue.Queue = queue.Queue(maxsize=depth)
            self._t = threading.Thread(target=self._run, name="dualtrack-reader", daemon=True)
            self._t.start()

    def _frames(self) -> Iterator[FramePair]:
        # threaded: two decoders, which overlap each other and the tracker
        it = self.seq.frames(1, self.stop_frame, workers=2 if self.threaded else 1)
        while True:
            t0 = time.perf_counter()
            try:
                fp = next(it)
            except StopIteration:
                return
            self.decode_s += time.perf_counter() - t0
            yield fp

    def _put(self, x: object) -> bool:
        while not self._stop.is_set():
            try:
                self._q.put(x, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _run(self) -> None:
        try:
            for fp in self._frames():
                if not self._put(fp):
                    return
        except (
            BaseException
        ) as exc:  # handed to the step's thread, which raises it at the right frame
            self._put(exc)
            return
        self._put(_END)

    def __iter__(self) -> Iterator[FramePair]:
        if not self.threaded:
            yield from self._frames()
            return
        while True:
            x = self._q.get()
            if x is _END:
                return
            if isinstance(x, BaseException):
                raise x
            yield x

    def close(self) -> None:
        self._stop.set()
        if self.threaded:
            self._t.join(timeout=30)


class _Writer:
    """Feeds the sinks in frame order (on its own thread, or inline), with a checkpoint on every
    ``every``-th frame that comes ``min_seconds`` or more after the last checkpoint."""

    def __init__(
        self,
        sinks: list[Sink],
        every: int,
        on_checkpoint: Callable[[int], None],
        threaded: bool,
        depth: int = 32,
        min_seconds: float = 0.0,
    ):
        self.sinks, self.every, self.on_checkpoint, self.threaded = (
            sinks,
            max(int(every), 1),
            on_checkpoint,
            threaded,
        )
        self.min_seconds = float(min_seconds)
        self._last_checkpoint = time.monotonic()
        self.written = 0  # frames on disk (at the last successful checkpoint)
        self.queued = 0
        self.sinks_s = 0.0
        self.error: BaseException | None = None
        self._n = 0
        if threaded:
            self._q: queue.Queue = queue.Queue(maxsize=depth)
            self._t = threading.Thread(target=self._run, name="dualtrack-writer", daemon=True)
            self._t.start()

    def _write(self, frames: FramePair, item: object) -> None:
        t0 = time.perf_counter()
        for s in self.sinks:
            s.write(frames, item)
        self._n += 1
        if (
            self._n % self.every == 0
            and time.monotonic() - self._last_checkpoint >= self.min_seconds
        ):
            self._checkpoint()
        self.sinks_s += time.perf_counter() - t0

    def _checkpoint(self) -> None:
        """Every sink durable, then summary.json; if any part fails the row files go back to the
        last checkpoint, so that they hold what summary.json says."""
        try:
            for s in self.sinks:
                s.checkpoint()
            self.on_checkpoint(self._n)
        except BaseException:
            for s in self.sinks:
                undo = getattr(s, "rollback", None)
                if undo is not None:
                    undo()
            raise
        self.written = self._n
        self._last_checkpoint = time.monotonic()

    def _run(self) -> None:
        while True:
            x = self._q.get()
            if x is _END:
                return
            if self.error is not None:
                continue  # drain: a sink failed, the rest of the frames are not written
            try:
                self._write(*x)
            except BaseException as exc:
                self.error = exc

    def put(self, frames: FramePair, item: object) -> None:
        if self.error is not None:
            raise self.error
        self.queued += 1
        if self.threaded:
            self._q.put((frames, item))
        else:
            try:
                self._write(frames, item)
            except BaseException as exc:
                self.error = exc
                raise

    def close(self) -> None:
        """Write what is queued, make it durable and close every sink (each is closed even if
        another fails)."""
        if self.threaded:
            self._q.put(_END)
            self._t.join()
        t0 = time.perf_counter()
        if self.error is None:
            try:
                self._checkpoint()
            except BaseException as exc:
                self.error = exc
        for s in self.sinks:
            try:
                s.close()
            except BaseException as exc:
                if self.error is None:
                    self.error = exc
        self.sinks_s += time.perf_counter() - t0


class _Signals:
    """SIGINT and SIGTERM set a flag the loop reads between frames; in ``holding()`` they only
    count."""

    def __init__(self) -> None:
        self.count = 0
        self._previous: dict[int, object] = {}
        self.active = threading.current_thread() is threading.main_thread()

    def _handler(self, signum: int, frame: object) -> None:
        self.count += 1

    def __enter__(self) -> _Signals:
        from pipeline._signals import taken

        self.count = taken()  # one the command took before the loop, that Python dropped
        if self.active:
            for s in (signal.SIGINT, signal.SIGTERM):
                self._previous[s] = signal.signal(s, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for s, h in self._previous.items():
            signal.signal(s, h)  # type: ignore[arg-type]


@contextmanager
def _timer(stats: LoopStats) -> Iterator[None]:
    t0 = time.perf_counter()
    try:
        yield
    finally:
        stats.wall_s = time.perf_counter() - t0


def run_job(job: Job) -> LoopResult:
    """Run ``job`` (module doc). Bad input before the first frame raises :class:`InputError`;
    anything that goes wrong later is reported in the result (``stats.error``,
    ``summary["error"]``) with every output valid."""
    from pipeline.sinks.summary import write_json

    prepare_out_dir(job.out_dir, job.force, job.files)
    summary = dict(job.summary)
    summary.update({"frames": 0, "complete": False})
    summary_path = job.out_dir / "summary.json"
    lock = threading.Lock()

    def write_summary(extra: dict[str, object]) -> None:
        with lock:
            summary.update(extra)
            try:
                write_json(summary_path, summary)
            except OSError as exc:
                raise OutputError(
                    f"cannot write {describe_os_error(exc, str(summary_path))}"
                ) from None

    write_summary({})
    stats = LoopStats()
    n_total = job.seq.n_frames if job.stop_frame is None else min(job.stop_frame, job.seq.n_frames)
    # until summary.json is final: SIGINT/SIGTERM stop between frames, then only count
    with _Signals() as sig:
        sinks = job.make_sinks()
        writer = _Writer(
            sinks,
            job.checkpoint_frames,
            lambda n: write_summary({"frames": n}),
            job.threads,
            min_seconds=job.checkpoint_min_seconds,
        )
        reader = _Reader(job.seq, job.stop_frame, job.threads)
        done = 0
        with _timer(stats):
            try:
                with Progress(n_total, job.label, enabled=job.progress) as bar:
                    for frames in reader:
                        if sig.count:
                            raise KeyboardInterrupt
                        t0, c0 = time.perf_counter(), time.thread_time()
                        item = job.step(frames)
                        stats.tracker_s += time.perf_counter() - t0
                        stats.tracker_cpu_s += time.thread_time() - c0
                        for k, v in getattr(item, "stage_seconds", {}).items():
                            stats.stage_s[k] = stats.stage_s.get(k, 0.0) + v
                        writer.put(frames, item)
                        done += 1
                        bar.update(1)
            except KeyboardInterrupt:
                stats.interrupted = True
            except InputError as exc:
                stats.error = str(exc)
            except OSError as exc:
                stats.error = describe_os_error(exc)
            except Exception as exc:
                # a bug in a step or a sink: the outputs still close and stay valid
                text = " ".join(str(exc).split())
                stats.error = f"internal error after {done} frames: {type(exc).__name__}: {text}"
                stats.crash = exc
            finally:
                reader.close()
                writer.close()
                stats.decode_s = reader.decode_s
                stats.sinks_s = writer.sinks_s
        if writer.error is not None and stats.error is None:
            e = writer.error
            stats.error = (
                str(e)
                if isinstance(e, InputError)
                else (
                    describe_os_error(e) if isinstance(e, OSError) else f"{type(e).__name__}: {e}"
                )
            )
        # a writer error cut the outputs back to their last checkpoint
        stats.frames = writer.written if writer.error is not None else done
        if sig.count and stats.error is None:
            stats.interrupted = True
        complete = not stats.interrupted and stats.error is None and stats.frames == n_total
        stage = dict(stats.stage_s)
        stage.update(
            {"decode": stats.decode_s, "tracker": stats.tracker_s, "sinks": stats.sinks_s}
        )
        final: dict[str, object] = {
            "frames": stats.frames,
            "stage_seconds": {k: round(v, 6) for k, v in stage.items()},
            "fps_tracking": round(done / stats.tracker_s, 3) if stats.tracker_s > 0 else None,
            "fps_tracking_cpu": round(done / stats.tracker_cpu_s, 3)
            if stats.tracker_cpu_s > 0
            else None,
            "fps_end_to_end": round(done / stats.wall_s, 3) if stats.wall_s > 0 else None,
            "complete": complete,
        }
        if stats.error is not None:
            final["error"] = stats.error
        if stats.interrupted:
            final["interrupted"] = True
        if job.finish is not None and stats.frames > 0 and writer.error is None:
            try:
                final.update(job.finish(stats))
            except InputError as exc:
                stats.error = stats.error or str(exc)
                final["error"] = stats.error
                final["complete"] = False
        try:
            write_summary(final)
        except (
            OutputError
        ) as exc:  # the disk is full: the last checkpoint's summary stays, true to the files
            stats.error = stats.error or str(exc)
        if sig.count and stats.error is None:
            stats.interrupted = True
    return LoopResult(job.out_dir, summary, stats)
