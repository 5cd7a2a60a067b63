"""Cost of Rerun logging per frame pair (docs/formats.md goal: <= 1 ms at 320x240).

Usage: python tools/rerun_cost.py [SEQ_DIR] [--frames N]

Decodes the frames first (not timed), then times RerunSink.write for every frame pair
(both images as source bytes, boxes on both channels, a 60-point contour, status,
centre error, two timings) plus the final close (flush + footer), and reports ms per
frame pair and the .rrd size.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    import cv2

    from pipeline.io.sequence import open_sequence
    from pipeline.sinks.rerun_sink import RerunSink
    from pipeline.sinks.settings import RerunConfig
    from pipeline.synthetic import synthesize
    from pipeline.types import (
        BBox,
        Event,
        EventKind,
        FrameResult,
        FrameTruth,
        TargetResult,
        TargetStatus,
        TruthMatch,
    )

    ap = argparse.ArgumentParser()
    ap.add_argument("seq", nargs="?", type=Path)
    ap.add_argument("--frames", type=int, default=200)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    with tempfile.TemporaryDirectory() as tmp:
        seq_dir = a.seq or synthesize("crossing2", Path(tmp) / "seq")
        seq = open_sequence(seq_dir)
        frames = [f for f, _ in zip(seq.frames(), range(a.frames), strict=False)]
        ang = np.linspace(0, 2 * np.pi, 60)
        results = []
        for f in frames:
            tg = []
            for tid in (1, 2):
                box = BBox(100 + f.index * 0.5 * tid, 90, 24, 60)
                contour = np.column_stack([box.cx + 12 * np.cos(ang), box.cy + 30 * np.sin(ang)])
                tg.append(
                    TargetResult(
                        tid,
                        box,
                        TargetStatus.TRACKING,
                        "levelset",
                        {"meanshift": 4, "levelset": 30},
                        0.9,
                        "updated:rho-high",
                        1.0,
                        (contour,),
                    )
                )
            ev = (Event(EventKind.MERGE, "T1+T2 merged", (1, 2)),) if f.index % 50 == 0 else ()
            results.append(
                FrameResult(f.index, tuple(tg), ev, {"meanshift": 4e-4, "levelset": 8e-4})
            )
        path = Path(tmp) / "run.rrd"
        sink = RerunSink(
            path, seq.channels, [1, 2], RerunConfig(), "cost", {"x": 1}, True, "start"
        )
        t0 = time.perf_counter()
        for f, r in zip(frames, results, strict=True):
            sink.write(
                f,
                r,
                FrameTruth(
                    {"visible": {1: r.targets[0].box}},
                    {1: 1.5, 2: 2.5},
                    {1: 0.8, 2: 0.7},
                    {1: TruthMatch.OVERLAP, 2: TruthMatch.OVERLAP},
                ),
            )
        t1 = time.perf_counter()
        sink.close()
        t2 = time.perf_counter()
        n = len(frames)
        print(
            f"{n} frame pairs {seq.width}x{seq.height}: write {1e3 * (t1 - t0) / n:.3f} ms/frame, "
            f"with close {1e3 * (t2 - t0) / n:.3f} ms/frame, .rrd "
            f"{path.stat().st_size / n / 1024:.1f} kB/frame"
        )


if __name__ == "__main__":
    main()
