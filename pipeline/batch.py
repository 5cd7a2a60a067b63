"""``dualtrack batch``: every sequence under an archive root, on this machine or a Dask cluster.

* :func:`discover` finds the sequence folders under ROOT (any layout the readers know,
  without reading frames; a sequence folder is not searched further; folders without
  frames are not sequences).
* :func:`plan` makes one :class:`Task` per (tracker, sequence) with its run folder,
  ``DIR/<sequence>/``, or ``DIR/<tracker>/<sequence>/`` with several trackers; a task whose
  run folder is complete (``summary.json`` says ``complete`` for the same tracker) is
  skipped unless ``force``.
* Every task runs ``dualtrack track`` in its own process (:func:`track_command`), so a
  crash, a corrupt frame or a killed process fails that sequence only. Locally a pool of
  ``workers`` threads (one per core by default) each drives one such process at a time.
  With a scheduler address, the tasks go to a Dask distributed cluster
  (:func:`remote_task`): the worker runs the same command in a scratch folder and sends
  the run folder's files back, which are written under DIR on this machine. Workers read
  the sequences at the same path as this machine (a shared or identically mounted disk)
  unless ``ship_frames``, which sends each sequence's files to the worker with the task.
* :func:`run_batch` collects the results, writes ``report.json``, ``report.md`` and the
  plots (``pipeline.sinks.report``) and, on request, each tracker's results in a
  toolkit's own format (``pipeline.sinks.export``). Ctrl-C stops the running processes;
  every finished sequence stays intact, and the report covers what finished.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from pipeline.errors import InputError
from pipeline.io.sequence import sequence_layout
from pipeline.trackers import DEFAULT_TRACKER, tracker_names

RUN_FILES = ("tracks.csv", "targets.csv", "summary.json", "run.rrd")
SINGLE_THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


@dataclass(frozen=True)
class BatchOptions:
    """Options of ``dualtrack batch`` (see ``dualtrack batch --help``).

    ``workers``: parallel sequences on this machine, default one per core; ``scheduler``:
    ``tcp://HOST:PORT`` of a Dask scheduler (then ``workers`` is ignored); ``protocol``:
    ``default|gtot|rgbt234|lasher|vtuav`` for every run and for the report's aggregation;
    ``export``: also write results in that toolkit's format; ``ship_frames``: with a
    scheduler, send each sequence's files to the worker instead of reading a shared path;
    ``timeout_s``: a sequence taking longer fails (None: no limit); ``channel``, ``align``,
    ``gt_base`` and ``stop_frame`` are ``track``'s ``--channel``, ``--align``, ``--gt-base`` and
    ``--frames`` for every run.
    """

    trackers: tuple[str, ...] = (DEFAULT_TRACKER,)
    workers: int | None = None
    scheduler: str | None = None
    force: bool = False
    protocol: str = "default"
    export: str | None = None
    sets: tuple[str, ...] = ()
    config_path: Path | None = None
    rrd: bool = True
    plots: bool = True
    ship_frames: bool = False
    timeout_s: float | None = None
    progress: bool | None = None
    channel: str | None = None
    align: str = "none"
    gt_base: float | None = None
    stop_frame: int | None = None


@dataclass(frozen=True)
class Task:
    """One tracker on one sequence."""

    key: str  # the report's name for it: "<sequence>" or "<tracker>/<sequence>"
    sequence: str  # name relative to ROOT
    seq_dir: Path
    tracker: str
    run_dir: Path


@dataclass
class TaskResult:
    """What happened to a task: ``done``, ``failed`` or ``skipped`` (already complete)."""

    task: Task
    status: str
    error: str | None = None
    seconds: float = 0.0
    summary: dict[str, object] = field(default_factory=dict)


def discover(root: Path, exclude: Path | None = None) -> list[tuple[str, Path]]:
    """``(name, folder)`` of every sequence under ``root`` (``root`` itself if it is one),
    sorted."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(
            f"archive root not found: {root}" if not root.exists() else f"not a folder: {root}"
        )
    ex = exclude.resolve() if exclude is not None else None
    found: list[tuple[str, Path]] = []

    def walk(d: Path) -> None:
        if ex is not None and (d.resolve() == ex or ex in d.resolve().parents):
            return
        if sequence_layout(d) is not None:
            name = d.relative_to(root).as_posix() if d != root else d.resolve().name
            found.append((name, d))
            return
        try:
            subs = sorted(p for p in d.iterdir() if p.is_dir() and not p.name.startswith("."))
        except OSError:
            return
        for p in subs:
            walk(p)

    walk(root)
    return found


def run_is_complete(run_dir: Path, tracker: str) -> dict[str, object] | None:
    """The summary of a complete run of ``tracker`` in ``run_dir``, else None."""
    import json

    f = run_dir / "summary.json"
    if not (f.is_file() and (run_dir / "tracks.csv").is_file()):
        return None
    try:
        s = json.loads(f.read_text())
    except (ValueError, OSError):
        return None
    return (
        s
        if isinstance(s, dict) and s.get("complete") is True and s.get("tracker") == tracker
        else None
    )


def plan(root: Path, out: Path, opts: BatchOptions) -> list[Task]:
    """The tasks of a batch, in sequence order then tracker order."""
    known = tracker_names()
    for t in opts.trackers:
        if t not in known:
            raise InputError(f"unknown tracker {t!r}; available: {', '.join(known)}")
    if len(set(opts.trackers)) != len(opts.trackers):
        raise InputError(f"--trackers names a tracker twice: {','.join(opts.trackers)}")
    seqs = discover(root, exclude=out)
    if not seqs:
        raise InputError(
            f"no sequence folders under {root} (looked for any layout dualtrack reads)"
        )
    several = len(opts.trackers) > 1
    tasks = []
    for name, d in seqs:
        for t in opts.trackers:
            run_dir = out / t / name if several else out / name
            tasks.append(Task(f"{t}/{name}" if several else name, name, d, t, run_dir))
    return tasks


def track_command(seq_dir: Path, tracker: str, run_dir: Path, opts: BatchOptions) -> list[str]:
    """The ``dualtrack track`` command line of one task."""
    cmd = [
        sys.executable,
        "-m",
        "pipeline",
        "track",
        str(seq_dir),
        "--tracker",
        tracker,
        "--out",
        str(run_dir),
        "--force",
        "--protocol",
        opts.protocol,
    ]
    if opts.config_path is not None:
        cmd += ["--config", str(opts.config_path)]
    for s in opts.sets:
        cmd += ["--set", s]
    if not opts.rrd:
        cmd.append("--no-rrd")
    if not opts.plots:
        cmd.append("--no-plots")
    if opts.channel is not None:
        cmd += ["--channel", opts.channel]
    if opts.align != "none":
        cmd += ["--align", opts.align]
    if opts.gt_base is not None:
        cmd += ["--gt-base", f"{opts.gt_base:g}"]
    if opts.stop_frame is not None:
        cmd += ["--frames", str(opts.stop_frame)]
    return cmd


def _last_error_line(stderr: str) -> str:
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    for ln in reversed(lines):
        if ln.startswith("dualtrack: error:"):
            return ln[len("dualtrack: error:") :].strip()
        if ln.startswith("dualtrack: internal error:"):
            return ln[len("dualtrack: ") :].strip()
    return lines[-1] if lines else ""


STOP_GRACE_S = 15.0
"""Seconds a stopped child gets to close its outputs after SIGTERM before it is killed."""


def run_process(
    cmd: list[str],
    timeout_s: float | None,
    procs: set[subprocess.Popen] | None = None,
    lock: threading.Lock | None = None,
) -> tuple[int, str]:
    """Run ``cmd`` single-threaded; ``(return code, error line)``. Tracks the process in ``procs``.

    The child dies with this process (``DUALTRACK_DIE_WITH_PARENT``: it asks the kernel for a
    SIGTERM when its parent goes, ``pipeline.cli``); a timeout stops it with SIGTERM first, so its
    outputs are closed, and kills it only if it has not ended ``STOP_GRACE_S`` later."""
    env = {
        **os.environ,
        **SINGLE_THREAD_ENV,
        "PYTHONUNBUFFERED": "1",
        "DUALTRACK_DIE_WITH_PARENT": str(os.getpid()),
    }
    p = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    if procs is not None and lock is not None:
        with lock:
            procs.add(p)
    try:
        try:
            _out, err = p.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            stop_process(p)
            p.communicate()
            return (
                -1,
                f"timed out after {timeout_s:g} s (stopped; its outputs hold the frames done)",
            )
    finally:
        if procs is not None and lock is not None:
            with lock:
                procs.discard(p)
    rc = p.returncode
    if rc < 0:
        try:
            name = signal.Signals(-rc).name
        except ValueError:
            name = str(-rc)
        return rc, f"the tracking process was killed ({name})"
    return rc, _last_error_line(err) if rc else ""


def _signal(p: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(p.pid, sig)
    except (ProcessLookupError, PermissionError):
        try:
            p.send_signal(sig)
        except ProcessLookupError:
            pass


def stop_process(p: subprocess.Popen, grace_s: float = STOP_GRACE_S) -> None:
    """SIGTERM (the child's run loop closes its outputs and writes summary.json), SIGKILL if it
    lingers."""
    _signal(p, signal.SIGTERM)
    try:
        p.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        _signal(p, signal.SIGKILL)


def _load_summary(run_dir: Path) -> dict[str, object]:
    import json

    try:
        s = json.loads((run_dir / "summary.json").read_text())
        return s if isinstance(s, dict) else {}
    except (ValueError, OSError):
        return {}


def _local_task(
    task: Task, opts: BatchOptions, procs: set[subprocess.Popen], lock: threading.Lock
) -> TaskResult:
    t0 = time.perf_counter()
    rc, err = run_process(
        track_command(task.seq_dir, task.tracker, task.run_dir, opts), opts.timeout_s, procs, lock
    )
    dt = time.perf_counter() - t0
    summary = _load_summary(task.run_dir)
    if rc == 0 and summary.get("complete") is True:
        return TaskResult(task, "done", None, dt, summary)
    return TaskResult(
        task, "failed", err or f"dualtrack track exited with status {rc}", dt, summary
    )


def run_local(
    tasks: list[Task], opts: BatchOptions, on_result: Callable[[TaskResult], None]
) -> None:
    """Run ``tasks`` on this machine, ``opts.workers`` at a time (default: one per core)."""
    workers = opts.workers or os.cpu_count() or 1
    procs: set[subprocess.Popen] = set()
    lock = threading.Lock()
    pool = ThreadPoolExecutor(max_workers=workers)
    pending: set[Future] = set()
    try:
        it = iter(tasks)
        for task in _take(it, workers):
            pending.add(pool.submit(_local_task, task, opts, procs, lock))
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                on_result(fut.result())
                for task in _take(it, 1):
                    pending.add(pool.submit(_local_task, task, opts, procs, lock))
    except BaseException:
        with lock:
            running = list(procs)
        for p in (
            running
        ):  # Ctrl-C / SIGTERM: stop the running sequences; they close their outputs (incomplete)
            _signal(p, signal.SIGTERM)
        deadline = time.monotonic() + STOP_GRACE_S
        for p in running:
            try:
                p.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                _signal(p, signal.SIGKILL)
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def _take(it: Iterator[Task], n: int) -> list[Task]:
    out = []
    for _ in range(n):
        try:
            out.append(next(it))
        except StopIteration:
            break
    return out


def _sequence_files(seq_dir: Path) -> dict[str, bytes]:
    """Every file of a sequence folder, by relative path (for ``ship_frames``)."""
    return {
        p.relative_to(seq_dir).as_posix(): p.read_bytes()
        for p in sorted(seq_dir.rglob("*"))
        if p.is_file()
    }


def remote_task(payload: dict[str, object]) -> dict[str, object]:
    """Run one task on a Dask worker; returns status, error, seconds and the run folder's files.

    ``payload``: ``seq_dir`` (a path the worker can read) or ``files`` (the shipped
    sequence), ``name``, ``tracker``, ``opts`` (a :class:`BatchOptions` as a dict).
    """
    opts = BatchOptions(**payload["opts"])  # type: ignore[arg-type]
    with tempfile.TemporaryDirectory(prefix="dualtrack-task-") as tmp:
        tmpd = Path(tmp)
        if payload.get("files") is not None:
            seq_dir = tmpd / "sequence" / Path(str(payload["name"])).name
            for rel, data in payload["files"].items():  # type: ignore[union-attr]
                f = seq_dir / rel
                f.parent.mkdir(parents=True, exist_ok=True)
                f.write_bytes(data)
        else:
            seq_dir = Path(str(payload["seq_dir"]))
        run_dir = tmpd / "run"
        t0 = time.perf_counter()
        rc, err = run_process(
            track_command(seq_dir, str(payload["tracker"]), run_dir, opts), opts.timeout_s
        )
        files = (
            {
                p.relative_to(run_dir).as_posix(): p.read_bytes()
                for p in sorted(run_dir.rglob("*"))
                if p.is_file()
            }
            if run_dir.is_dir()
            else {}
        )
        return {"rc": rc, "error": err, "seconds": time.perf_counter() - t0, "files": files}


def run_dask(
    tasks: list[Task], opts: BatchOptions, on_result: Callable[[TaskResult], None]
) -> None:
    """Submit ``tasks`` to the Dask scheduler at ``opts.scheduler``; write results back under
    DIR."""
    import dataclasses

    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise InputError(
            "--scheduler needs dask.distributed: pip install -e '.[cluster]'"
        ) from None
    from pipeline.sinks.batch_files import write_run_files

    try:
        client = Client(opts.scheduler, timeout="20s")
    except (OSError, TimeoutError) as e:
        raise InputError(f"cannot reach the Dask scheduler at {opts.scheduler}: {e}") from None
    odict = {
        k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(opts).items()
    }
    odict["progress"] = False
    try:
        futures = {}
        for task in tasks:
            payload: dict[str, object] = {
                "name": task.sequence,
                "tracker": task.tracker,
                "opts": odict,
                "seq_dir": str(task.seq_dir.resolve()),
            }
            if opts.ship_frames:
                payload["files"] = _sequence_files(task.seq_dir)
            fut = client.submit(
                remote_task, payload, pure=False, key=f"dualtrack-{task.key}-{time.time_ns()}"
            )
            futures[fut] = task
        for fut in as_completed(list(futures)):
            task = futures[fut]
            try:
                r = fut.result()
            except Exception as e:  # the worker died (KilledWorker) or the task raised
                on_result(TaskResult(task, "failed", f"{type(e).__name__}: {e}".strip()))
                continue
            if r["files"]:
                write_run_files(task.run_dir, r["files"])  # type: ignore[arg-type]
            summary = _load_summary(task.run_dir) if r["files"] else {}
            ok = r["rc"] == 0 and summary.get("complete") is True
            on_result(
                TaskResult(
                    task,
                    "done" if ok else "failed",
                    None
                    if ok
                    else (r["error"] or f"dualtrack track exited with status {r['rc']}"),
                    float(r["seconds"]),
                    summary,
                )
            )  # type: ignore[arg-type]
    finally:
        for fut in futures:
            fut.cancel()
        client.close()


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM stops a batch as Ctrl-C does (children stopped, report written); outside the main
    thread, nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@dataclass
class BatchResult:
    """The results of a batch, in task order, and where the report is."""

    out_dir: Path
    results: list[TaskResult]
    wall_seconds: float
    interrupted: bool = False


def run_batch(root: Path, out: Path, opts: BatchOptions) -> BatchResult:
    """Plan, run (locally or on Dask), report. See the module doc."""
    from pipeline.eval.protocols import PROTOCOLS
    from pipeline.progress import Progress
    from pipeline.sinks.report import write_progress_report, write_report

    if opts.protocol not in PROTOCOLS:
        raise InputError(
            f"--protocol must be one of {', '.join(PROTOCOLS)}; got {opts.protocol!r}"
        )
    from pipeline.sinks.export import EXPORT_FORMATS

    if opts.export is not None and opts.export not in EXPORT_FORMATS:
        raise InputError(
            f"--export must be one of {', '.join(EXPORT_FORMATS)}; got {opts.export!r}"
        )
    if opts.workers is not None and opts.workers < 1:
        raise InputError(f"--workers must be at least 1; got {opts.workers}")
    if opts.timeout_s is not None and not opts.timeout_s > 0:
        raise InputError(f"--timeout must be a positive number of seconds; got {opts.timeout_s:g}")
    from pipeline.config import load_config

    load_config(
        opts.config_path, list(opts.sets)
    )  # a bad --set or config file stops the batch before it starts
    root, out = Path(root), Path(out)
    tasks = plan(root, out, opts)
    from pipeline.runloop import prepare_out_dir

    prepare_out_dir(out, True, ())
    results: dict[str, TaskResult] = {}
    todo = []
    for t in tasks:
        done = None if opts.force else run_is_complete(t.run_dir, t.tracker)
        if done is not None:
            results[t.key] = TaskResult(t, "skipped", None, 0.0, done)
        else:
            if opts.force and t.run_dir.exists():
                shutil.rmtree(t.run_dir)
            todo.append(t)
    t0 = time.perf_counter()
    frames = 0
    counts = {"done": 0, "failed": 0}
    interrupted = False
    with Progress(len(todo), "batch", enabled=opts.progress, unit="runs") as bar:

        def on_result(r: TaskResult) -> None:
            nonlocal frames
            results[r.task.key] = r
            counts[r.status] = counts.get(r.status, 0) + 1
            frames += int(r.summary.get("frames", 0) or 0)  # type: ignore[call-overload]
            rate = frames / max(time.perf_counter() - t0, 1e-9)
            bar.update(1, failed=counts["failed"], frames=f"{rate:.0f}/s")
            write_progress_report(
                out,
                [results[t.key] for t in tasks if t.key in results],
                opts,
                len(tasks),
                time.perf_counter() - t0,
            )

        try:
            with _sigterm_as_interrupt():
                if todo:
                    (run_dask if opts.scheduler else run_local)(todo, opts, on_result)
        except KeyboardInterrupt:
            interrupted = True
    wall = time.perf_counter() - t0
    ordered = [results[t.key] for t in tasks if t.key in results]
    write_report(out, ordered, opts, wall, interrupted)
    if opts.export:
        from pipeline.sinks.export import export_mot, export_results

        finished = [r for r in ordered if r.status in ("done", "skipped")]
        if opts.export == "mot":
            export_mot(out, finished)
        else:
            export_results(out, finished, opts.export)
    return BatchResult(out, ordered, wall, interrupted)
