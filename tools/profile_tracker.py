"""Where a tracker's time goes: ms a frame per part, and how much of it is compiled code.

The tracker alone runs over frames decoded beforehand (no decoding, no sinks), once to warm
up and once under ``cProfile``; each function's own time is charged to the part of the
tracker its module belongs to (:data:`PARTS`), and counted as *compiled* when it is a C
function (NumPy, SciPy, OpenCV) or a Numba kernel (Numba shows a compiled call to the profiler
as a call of the kernel's Python function, with the kernel's own time). The rest is the Python
layer. One core (thread pools of one, as ``dualtrack bench``). Profiling adds its own cost to
every Python call, so the Python share here is an upper bound; the total is also printed as the
unprofiled CPU time of the same loop.

Usage::

    python tools/profile_tracker.py                   # the eight named scenes, dual
    python tools/profile_tracker.py --scenes fast --tracker meanshift
    python tools/profile_tracker.py --seq path/to/sequence --frames 200
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"  # one core, as dualtrack bench: CPU time is then the work's own


PARTS = (
    ("filter", ("stages/appearance", "trackers/dual/appearance", "scipy/fft", "numpy/fft")),
    ("level set", ("stages/levelset", "stages/contour", "trackers/dual/contour")),
    ("mean shift", ("stages/meanshift", "stages/histogram", "trackers/dual/colour")),
    ("colour extent", ("stages/extent", "trackers/dual/size")),
    ("Kalman", ("stages/kalman", "trackers/dual/motion", "stages/motion")),
    ("detection", ("stages/detection", "trackers/dual/redetect")),
    ("decision", ("trackers/dual/decide", "trackers/dual/group", "trackers/dual/lifecycle")),
)
"""Part of the tracker -> path fragments of the modules whose functions it charges. A C
function is charged to the part of the Python function that called it."""

SHARED = ("stages/_labels",)
"""Path fragments of helper modules several parts call: their functions, and the C functions they
call, are charged to the parts of their callers."""


def _part_of(filename: str) -> str | None:
    f = filename.replace("\\", "/")
    for part, frags in PARTS:
        if any(fr in f for fr in frags):
            return part
    return None


def _kernel_keys() -> set[tuple[str, int, str]]:
    """``(file, first line, name)`` of every Numba kernel's Python function in the pipeline's
    modules: Numba (0.59 and later, the project's floor) shows a compiled call to the profiler
    as a call of that function, so its time is listed under the kernel's own source and counts
    as compiled."""
    import numba.core.registry

    keys = set()
    for name, mod in list(sys.modules.items()):
        if not name.startswith("pipeline") or mod is None:
            continue
        for obj in vars(mod).values():
            if isinstance(obj, numba.core.registry.CPUDispatcher):
                code = obj.py_func.__code__
                keys.add((code.co_filename, code.co_firstlineno, code.co_name))
    return keys


def _engine(seq: object, tracker: str) -> object:
    from pipeline.config import PipelineConfig
    from pipeline.trackers import make_tracker
    from pipeline.trackers.base import attach_sequence

    engine = make_tracker(tracker, PipelineConfig())
    attach_sequence(engine, seq)
    return engine


def _loop(engine: object, pairs: list, targets: list) -> None:
    engine.start(pairs[0], targets)  # type: ignore[attr-defined]
    for p in pairs[1:]:
        engine.step(p)  # type: ignore[attr-defined]


def profile(seq_dir: Path, tracker: str, frames: int | None) -> dict[str, object]:
    """Profile ``tracker`` on ``seq_dir``: ``{"frames", "cpu_ms", "parts": {part: (ms,
    compiled ms)}}``, ms a frame (``start`` on frame 1 not counted in the CPU time)."""
    from pipeline.io.init import resolve_init
    from pipeline.io.sequence import open_sequence

    seq = open_sequence(seq_dir)
    pairs = list(seq.frames(1, frames))
    targets = resolve_init(seq, None)
    _loop(_engine(seq, tracker), pairs, targets)  # warm-up: kernels compiled, caches filled
    engine = _engine(seq, tracker)
    engine.start(pairs[0], targets)  # type: ignore[attr-defined]
    c0 = time.process_time()
    for p in pairs[1:]:
        engine.step(p)  # type: ignore[attr-defined]
    cpu = time.process_time() - c0
    engine = _engine(seq, tracker)
    engine.start(pairs[0], targets)  # type: ignore[attr-defined]
    prof = cProfile.Profile()
    prof.enable()
    for p in pairs[1:]:
        engine.step(p)  # type: ignore[attr-defined]
    prof.disable()
    n = len(pairs) - 1
    return {"frames": n, "cpu_ms": 1000 * cpu / n, "parts": _charge(prof, n, _kernel_keys())}


def _charge(
    prof: cProfile.Profile, n: int, kernels: set[tuple[str, int, str]] = frozenset()
) -> dict[str, tuple[float, float]]:
    st = pstats.Stats(prof)
    stats = st.stats  # type: ignore[attr-defined]
    own: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])

    def shares(key: tuple[str, int, str], depth: int = 0) -> dict[str, float]:
        """The parts a C or shared function's time goes to, as shares of it: its callers'."""
        by: dict[str, float] = defaultdict(float)
        for caller, c in stats[key][4].items():
            cf = caller[0]
            if (cf == "~" or any(f in cf for f in SHARED)) and caller in stats and depth < 4:
                for p, w in shares(caller, depth + 1).items():
                    by[p] += c[2] * w
            else:
                by[_part_of(cf) or "glue"] += c[2]
        total = sum(by.values()) or 1.0
        return {p: t / total for p, t in by.items()} or {"glue": 1.0}

    for key, (_cc, _nc, tt, _ct, _callers) in stats.items():
        filename = key[0]
        compiled = filename == "~" or key in kernels
        part = _part_of(filename)
        if part is None and (filename == "~" or any(f in filename for f in SHARED)):
            for p, w in shares(key).items():  # the part (or parts) of its callers
                own[p][0] += tt * w
                own[p][1] += tt * w if compiled else 0.0
            continue
        part = part or "glue"
        own[part][0] += tt
        if compiled:
            own[part][1] += tt
    return {p: (1000 * a / n, 1000 * b / n) for p, (a, b) in own.items()}


def table(results: dict[str, dict[str, object]]) -> str:
    """The mean over scenes, as a Markdown table."""
    parts: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])
    cpu = 0.0
    for r in results.values():
        cpu += r["cpu_ms"] / len(results)  # type: ignore[operator]
        for p, (ms, comp) in r["parts"].items():  # type: ignore[union-attr]
            parts[p][0] += ms / len(results)
            parts[p][1] += comp / len(results)
    order = [p for p, _ in PARTS] + ["glue"]
    total = sum(v[0] for v in parts.values())
    comp = sum(v[1] for v in parts.values())
    lines = [
        "| part | ms a frame (profiled) | compiled |",
        "|---|---|---|",
    ]
    for p in order:
        if p in parts:
            ms, c = parts[p]
            lines.append(f"| {p} | {ms:.3f} | {100 * c / ms if ms else 0:.0f} % |")
    lines.append(f"| **all (profiled)** | {total:.3f} | {100 * comp / total:.0f} % |")
    lines.append(f"| **all (unprofiled CPU time)** | {cpu:.3f} | |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tracker", default="dual")
    ap.add_argument("--scenes", nargs="*", help="named synthetic scenes (default: the eight)")
    ap.add_argument("--seq", type=Path, action="append", help="a sequence folder instead")
    ap.add_argument("--frames", type=int, default=None, help="only the first N frames")
    a = ap.parse_args()
    import cv2

    from pipeline.synthetic import ONE_TARGET_SCENES, synthesize

    cv2.setNumThreads(1)

    results: dict[str, dict[str, object]] = {}
    with tempfile.TemporaryDirectory(prefix="dualtrack-profile-") as tmp:
        seqs = list(a.seq or [])
        if not a.seq:
            names = a.scenes or ONE_TARGET_SCENES
            seqs = [synthesize(s, Path(tmp) / s, seed=0, progress=False) for s in names]
        for seq in seqs:
            results[Path(seq).name] = r = profile(Path(seq), a.tracker, a.frames)
            print(f"{Path(seq).name}: {r['cpu_ms']:.3f} ms a frame (CPU)", file=sys.stderr)
    print(table(results))


if __name__ == "__main__":
    main()
