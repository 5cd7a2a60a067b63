"""Run the field's multi-object trackers on detection files: the half of ``tools/mot_peers.py``
that runs in the peers' own environment (``tools/mot_peer_venv.sh``).

It imports only numpy, ``supervision`` and Roboflow's ``trackers`` (clean-room ByteTrack, OC-SORT
and SORT at their default parameters), not dualtrack: ``supervision`` depends on the non-headless
OpenCV wheel, which conflicts with dualtrack's. Input: a JSON file listing jobs
``{"dets": FILE, "frames": N, "out": {tracker: FILE}}``, each ``dets`` of MOTChallenge rows
``frame,-1,x,y,w,h,score`` (1-based); output: per tracker a MOTChallenge results file of the
confirmed tracks' boxes, and the seconds each tracker took on stdout as JSON.

    .venv-mot/bin/python tools/mot_peer_worker.py JOBS.json
"""

from __future__ import annotations

import json
import sys
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
import supervision as sv
import trackers

TRACKERS = {
    "bytetrack": trackers.ByteTrackTracker,
    "ocsort": trackers.OCSORTTracker,
    "sort": trackers.SORTTracker,
}


def _read(path: Path, frames: int) -> list[np.ndarray]:
    """Per frame an (K, 5) array ``x1, y1, x2, y2, score`` in 0-based px."""
    per = [np.zeros((0, 5)) for _ in range(frames)]
    rows = [r.split(",") for r in path.read_text().splitlines() if r.strip()]
    if rows:
        a = np.array([[float(v) for v in r[:7]] for r in rows])
        for f in range(frames):
            m = a[:, 0] == f + 1
            x, y, w, h = a[m, 2] - 1, a[m, 3] - 1, a[m, 4], a[m, 5]
            per[f] = np.stack([x, y, x + w, y + h, a[m, 6]], axis=1)
    return per


def run(name: str, per_frame: list[np.ndarray]) -> tuple[list[str], float]:
    """MOTChallenge rows (1-based) of tracker ``name`` over the frames, and its seconds."""
    tracker = TRACKERS[name]()
    rows: list[str] = []
    t0 = time.perf_counter()
    for f, d in enumerate(per_frame):
        dets = sv.Detections(
            xyxy=d[:, :4].astype(np.float32),
            confidence=d[:, 4].astype(np.float32),
            class_id=np.zeros(len(d), int),
        )
        out = tracker.update(dets)
        ids = out.tracker_id if out.tracker_id is not None else np.full(len(out), -1)
        for (x1, y1, x2, y2), tid in zip(out.xyxy, ids, strict=True):
            if tid is None or int(tid) < 0:
                continue  # not yet confirmed
            rows.append(
                f"{f + 1},{int(tid) + 1},{x1 + 1:.2f},{y1 + 1:.2f},{x2 - x1:.2f},{y2 - y1:.2f},"
                "1,-1,-1,-1"
            )
    return rows, time.perf_counter() - t0


def main(argv: list[str]) -> int:
    jobs = json.loads(Path(argv[0]).read_text())
    seconds: dict[str, float] = {name: 0.0 for name in TRACKERS}
    for job in jobs:
        per = _read(Path(job["dets"]), int(job["frames"]))
        for name, out in job["out"].items():
            rows, s = run(name, per)
            seconds[name] += s
            Path(out).write_text("\n".join(rows) + ("\n" if rows else ""))
    print(
        json.dumps(
            {
                "seconds": seconds,
                "versions": {
                    "supervision": sv.__version__,
                    "trackers": version("trackers"),
                },
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
