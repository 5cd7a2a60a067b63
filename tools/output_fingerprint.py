"""Fingerprint the dual tracker's output, to check that a speed-up changed nothing.

Usage: python tools/output_fingerprint.py [--scenes-dir DIR] [--only KEY,...] [--save FILE |
--check FILE]

Renders (once, into DIR; default ``runs/fingerprint-scenes``) the eight single-target scenes with
seeds 0 and 2, the four multi-target scenes with seed 0 and three scenes of the random family's
development range, runs ``dual`` on each (no .rrd, no plots), then the variants of :data:`VARIANTS`
on some of them (the paper's configuration, merge handling, one channel, the other engines of the
project), and prints the SHA-256 of every ``targets.csv``. ``--save FILE`` writes them as JSON;
``--check FILE`` compares with a saved set and exits 1 naming the runs whose output differs, with
how their scores moved (P@20, AUC, IDF1 from ``summary.json``) and the mean change over all runs.
``--only`` limits the runs to some keys (``fast-s0,group3-s0``).

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

SINGLE = (
    "approach",
    "crossover",
    "dusk",
    "fast",
    "hot-distractor",
    "lookalike",
    "occluder",
    "shadows",
)
MULTI = ("crossing2", "crossing3", "meet-part", "group3")
RANDOM = (("random-7", 7, 1), ("random-11", 11, 3), ("random-12", 12, 2))  # development seeds
RUNS = [(s, 0) for s in SINGLE] + [(s, 2) for s in SINGLE] + [(s, 0) for s in MULTI]
# variant -> (tracker, --set items, --channel, scenes); "<variant>:<scene>-s<seed>" keys
VARIANTS: dict[str, tuple[str, tuple[str, ...], str | None, tuple[str, ...]]] = {
    "paper": (
        "dual",
        ("@data/dual-paper.toml",),
        None,
        ("crossing2-s0", "crossing3-s0", "meet-part-s0", "group3-s0", "shadows-s0", "random-11"),
    ),
    "merge": (
        "dual",
        ("dual.groups=default",),
        None,
        ("crossing2-s0", "crossing3-s0", "meet-part-s0", "group3-s0", "random-11", "random-12"),
    ),
    "ir": ("dual", (), "infrared", ("crossover-s0", "occluder-s0", "crossing2-s0", "random-7")),
    "visible": ("dual", (), "visible", ("dusk-s0", "lookalike-s0", "crossing2-s0", "random-7")),
    "kalman-camshift": ("kalman-camshift", (), None, ("occluder-s0", "fast-s0", "random-7")),
    "meanshift": ("meanshift", (), None, ("occluder-s0", "random-7")),
    "detect": ("detect", (), None, ("crossing3-s0", "random-11")),
}


def all_keys() -> list[str]:
    """Every run key: ``<scene>-s<seed>`` and ``random-<seed>`` for ``dual``, ``<variant>:<scene>``
    for the rest."""
    keys = [f"{s}-s{d}" for s, d in RUNS] + [name for name, _, _ in RANDOM]
    return keys + [f"{v}:{scene}" for v, (_, _, _, scenes) in VARIANTS.items() for scene in scenes]


def _scene(scenes_dir: Path, name: str) -> Path:
    from pipeline.synthetic import synthesize, synthesize_random

    seq = scenes_dir / name
    if not seq.exists():
        rnd = {n: (seed, k) for n, seed, k in RANDOM}
        if name in rnd:
            synthesize_random(seq, rnd[name][0], targets=rnd[name][1], progress=False)
        else:
            scene, _, seed = name.rpartition("-s")
            synthesize(scene, seq, seed=int(seed))
    return seq


SCORES = ("p20", "auc", "idf1")


def _scores(summary: dict) -> dict[str, float]:
    """The run's scores of :data:`SCORES` (NaN where it has none; saved as ``null``)."""
    ev = summary.get("metrics") or {}
    out = {}
    for k in SCORES:
        v = ev.get(k, summary.get(k))
        out[k] = float(v) if isinstance(v, int | float) else float("nan")
    return out


def fingerprints(scenes_dir: Path, only: set[str] | None = None) -> dict[str, dict]:
    """``{key: {"sha": sha256 of targets.csv, "p20", "auc", "idf1"}}`` for every run of
    :func:`all_keys` (or those in ``only``)."""
    import cv2

    from pipeline.run import RunOptions, run_track

    cv2.setNumThreads(1)
    root = Path(__file__).resolve().parents[1]
    out: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="dualtrack-fingerprint-") as tmp:
        for key in all_keys():
            if only is not None and key not in only:
                continue
            variant, _, scene = key.rpartition(":")
            tracker, sets, channel = "dual", (), None
            if variant:
                tracker, sets, channel, _ = VARIANTS[variant]
            config = next((root / s[1:] for s in sets if s.startswith("@")), None)
            opts = RunOptions(
                tracker=tracker,
                out_dir=Path(tmp) / key.replace(":", "_"),
                rrd=False,
                plots=False,
                force=True,
                channel=channel,
                config_path=config,
                sets=[s for s in sets if not s.startswith("@")],
                progress=False,
            )
            run_track(_scene(scenes_dir, scene), opts)
            sha = hashlib.sha256((opts.out_dir / "targets.csv").read_bytes()).hexdigest()
            summary = json.loads((opts.out_dir / "summary.json").read_text())
            out[key] = {"sha": sha, **_scores(summary)}
            print(f"{key:32s} {sha[:16]}", flush=True)
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
    keys = set(all_keys())
    only = {k for k in a.only.split(",") if k} or None
    if only is not None and only - keys:
        print(
            f"error: unknown run {sorted(only - keys)[0]!r}; runs: {', '.join(sorted(keys))}",
            file=sys.stderr,
        )
        return 2
    got = fingerprints(a.scenes_dir, only)
    if a.save is not None:
        plain = {k: {s: (None if v != v else v) for s, v in e.items()} for k, e in got.items()}
        a.save.write_text(json.dumps(plain, indent=1, allow_nan=False) + "\n")
        print(f"saved {len(got)} fingerprints to {a.save}")
    if a.check is not None:
        want = {
            k: {s: float("nan") if x is None else x for s, x in v.items()}
            if isinstance(v, dict)
            else {"sha": v}
            for k, v in json.loads(a.check.read_text()).items()
        }
        if only is not None:
            want = {k: v for k, v in want.items() if k in only}
        diff = sorted(
            k
            for k in set(want) | set(got)
            if want.get(k, {}).get("sha") != got.get(k, {}).get("sha")
        )
        if diff:
            print("output differs: " + ", ".join(diff), file=sys.stderr)
            _moves(want, got, diff)
            return 1
        print(f"all {len(got)} runs byte-identical")
    return 0


def _moves(want: dict[str, dict], got: dict[str, dict], diff: list[str]) -> None:
    """How the differing runs' scores moved, and the mean change over every run."""
    if not all("p20" in want.get(k, {}) and k in got for k in diff):
        return  # a fingerprint file of hashes only
    print(f"{'run':32s} " + " ".join(f"{'d' + k:>8s}" for k in SCORES), file=sys.stderr)
    for k in diff:
        d = [got[k][s] - want[k][s] for s in SCORES]
        print(f"{k:32s} " + " ".join(f"{v:+8.3f}" for v in d), file=sys.stderr)
    both = [k for k in got if k in want]
    mean = []
    for s in SCORES:
        vals = [got[k][s] - want[k][s] for k in both if got[k][s] == got[k][s]]
        mean.append(sum(vals) / max(len(vals), 1))
    label = f"mean over {len(both)} runs"
    print(f"{label:32s} " + " ".join(f"{v:+8.4f}" for v in mean), file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
