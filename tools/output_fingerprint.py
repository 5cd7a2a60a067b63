"""Fingerprint the dual tracker's output, to check that a speed-up changed nothing.

Usage: python tools/output_fingerprint.py [--scenes-dir DIR] [--only KEY,...] [--save FILE | --check FILE]

Renders (once, into DIR; default ``runs/fingerprint-scenes``) the eight single-target scenes
with seeds 0 and 2 and the four multi-target scenes with seed 0, runs ``dual`` on each
(no .rrd, no plots) and prints the SHA-256 of every ``targets.csv``. ``--save FILE`` writes
them as JSON; ``--check FILE`` compares with a saved set and exits 1 naming the runs whose
output differs. ``--only`` limits the runs to some keys (``fast-s0,group3-s0``).

Why: the tracker's output is sensitive to float32 rounding in the level set (a rounding-level
change flipped whole sequences, see README, Development), so a change meant to be only faster
should leave every ``targets.csv`` byte-identical. Save on the commit before the change, check
after it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

SINGLE = ("approach", "crossover", "dusk", "fast", "hot-distractor", "lookalike", "occluder", "shadows")
MULTI = ("crossing2", "crossing3", "meet-part", "group3")
RUNS = [(s, 0) for s in SINGLE] + [(s, 2) for s in SINGLE] + [(s, 0) for s in MULTI]


def fingerprints(scenes_dir: Path, only: set[str] | None = None) -> dict[str, str]:
    """``{"<scene>-s<seed>": sha256 of targets.csv}`` for every run of :data:`RUNS` (or those in ``only``)."""
    import cv2

    from pipeline.run import RunOptions, run_track
    from pipeline.synthetic import synthesize

    cv2.setNumThreads(1)
    out: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="dualtrack-fingerprint-") as tmp:
        for scene, seed in RUNS:
            key = f"{scene}-s{seed}"
            if only is not None and key not in only:
                continue
            seq = scenes_dir / key
            if not seq.exists():
                synthesize(scene, seq, seed=seed)
            run = Path(tmp) / key
            run_track(seq, RunOptions(tracker="dual", out_dir=run, rrd=False, plots=False, force=True))
            out[key] = hashlib.sha256((run / "targets.csv").read_bytes()).hexdigest()
            print(f"{key:24s} {out[key][:16]}", flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes-dir", type=Path, default=Path("runs/fingerprint-scenes"))
    ap.add_argument("--only", default="", help="comma-separated run keys, e.g. fast-s0,group3-s0")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--save", type=Path)
    group.add_argument("--check", type=Path)
    a = ap.parse_args()
    if a.check is not None and not a.check.is_file():
        print(f"error: no fingerprint file {a.check}", file=sys.stderr)
        return 2
    keys = {f"{s}-s{d}" for s, d in RUNS}
    only = {k for k in a.only.split(",") if k} or None
    if only is not None and only - keys:
        print(f"error: unknown run {sorted(only - keys)[0]!r}; runs: {', '.join(sorted(keys))}", file=sys.stderr)
        return 2
    got = fingerprints(a.scenes_dir, only)
    if a.save is not None:
        a.save.write_text(json.dumps(got, indent=1) + "\n")
        print(f"saved {len(got)} fingerprints to {a.save}")
    if a.check is not None:
        want = json.loads(a.check.read_text())
        if only is not None:
            want = {k: v for k, v in want.items() if k in only}
        diff = sorted(k for k in set(want) | set(got) if want.get(k) != got.get(k))
        if diff:
            print("output differs: " + ", ".join(diff), file=sys.stderr)
            return 1
        print(f"all {len(got)} runs byte-identical")
    return 0


if __name__ == "__main__":
    sys.exit(main())
