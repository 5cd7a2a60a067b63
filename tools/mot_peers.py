"""The detection-driven tracker against the field's multi-object trackers on the same detections.

For each random scene (:mod:`pipeline.synthetic.family`): ``dualtrack detect`` writes the
detector's regions; the detections the ``detect`` tracker itself uses (accepted IR regions of
at least ``detect.association.min_perimeter_px`` boundary, with the score ``det.txt``
carries) go to ByteTrack, OC-SORT and SORT (Roboflow's ``trackers`` at their default
parameters, run by ``tools/mot_peer_worker.py`` in their own environment, made by
``tools/mot_peer_venv.sh``), once with those scores and once with every score 1 (their
two-stage association then sees one class of detection); ``dualtrack track --tracker detect``
runs on the same scene. Every result is scored by ``dualtrack evaluate`` (ids matched by the
IDF1 assignment). Prints per tracker the mean, 10th percentile and worst of IDF1, with MOTA,
HOTA and purity means, and the trackers' own seconds; and two ceilings (:func:`perfect_ids`):
the ``detect`` tracker's boxes and the detections, each box given the id of the target it
overlaps. The tracker's own figure below its boxes' ceiling is what it loses in identities; the
boxes' ceiling below the detections' is what its boxes lose against the detector's.

    tools/mot_peer_venv.sh                      # once: .venv-mot
    python tools/mot_peers.py --seeds 1500-1519 --out runs/mot-peers [--json r.json]

Scenes are generated into ``OUT/scenes`` unless there, and the detections and the ``detect``
runs of an earlier call into the same ``OUT`` are reused (``--force`` makes them again, after a
code change); development seeds are 0-999, test seeds 1000-1999 (score those once, never tune
on them).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PEERS = ("bytetrack", "ocsort", "sort")


def tracker_regions(rois: Path, min_perimeter_px: float) -> Iterator[dict[str, str]]:
    """The ``rois.csv`` rows of the regions the ``detect`` tracker uses: accepted IR regions
    (reason ``ok``) of at least ``min_perimeter_px`` boundary."""
    with rois.open() as f:
        for r in csv.DictReader(f):
            if r["accepted"] == "1" and r["reason"] == "ok":
                if float(r["perimeter_px"]) >= min_perimeter_px:
                    yield r


def _dets(rois: Path, min_perimeter_px: float) -> list[str]:
    """``det.txt`` rows (1-based) of the regions the ``detect`` tracker uses (the score of
    ``rois.csv``; ``1 / C2`` for files written before it had one)."""
    rows = []
    for r in tracker_regions(rois, min_perimeter_px):
        x, y, w, h = (float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))
        shape = min(1.0, 1.0 / max(float(r["c2"]), 1.0))
        conf = float(r["score"]) if r.get("score") else shape
        rows.append(f"{r['frame']},-1,{x + 1:.2f},{y + 1:.2f},{w:.2f},{h:.2f},{conf:.3f}")
    return rows


def perfect_ids(
    boxes: dict[int, list[tuple[float, float, float, float]]],
    truth: dict[int, np.ndarray],
    first_free: int = 1_000_000,
) -> list[str]:
    """MOTChallenge rows (1-based) of ``boxes`` (frame -> 0-based ``(x, y, w, h)``) with the ids
    a perfect association would give them: on every frame, the truth id of the target a box
    overlaps at IoU >= 0.5 in the one-to-one assignment of highest total IoU, and a fresh id
    from ``first_free`` on for a box on no target. ``truth`` is target id -> ``(frames, 4)``
    0-based boxes, NaN where absent (:meth:`pipeline.io.sequence.Truth.primary`). Scored, these
    rows are the identity ceiling of the boxes: what they reach when no identity is lost.

    Examples
    --------
    >>> truth = {1: np.array([[0.0, 0, 10, 10]]), 2: np.array([[20.0, 0, 10, 10]])}
    >>> perfect_ids({1: [(21.0, 0, 10, 10), (0.0, 1, 10, 10), (50.0, 50, 5, 5)]}, truth, 9)
    ['1,2,22.00,1.00,10.00,10.00,1,-1,-1,-1', '1,1,1.00,2.00,10.00,10.00,1,-1,-1,-1', \
'1,9,51.00,51.00,5.00,5.00,1,-1,-1,-1']
    """
    from scipy.optimize import linear_sum_assignment

    from pipeline.eval.mot import box_ious

    rows, fresh = [], first_free
    for f in sorted(boxes):
        bs = boxes[f]
        ids = [g for g, b in truth.items() if f - 1 < len(b) and not np.isnan(b[f - 1]).any()]
        named: dict[int, int] = {}
        if bs and ids:
            iou = box_ious(np.array(bs, float), np.array([truth[g][f - 1] for g in ids]))
            for i, j in zip(*linear_sum_assignment(-iou), strict=True):
                if iou[i, j] >= 0.5:
                    named[int(i)] = ids[j]
        for k, (x, y, w, h) in enumerate(bs):
            if k not in named:
                named[k], fresh = fresh, fresh + 1
            rows.append(f"{f},{named[k]},{x + 1:.2f},{y + 1:.2f},{w:.2f},{h:.2f},1,-1,-1,-1")
    return rows


def _boxes(mot_rows: list[str] | Path) -> dict[int, list[tuple[float, float, float, float]]]:
    """frame -> 0-based boxes of MOTChallenge rows (a file or its lines)."""
    lines = mot_rows.read_text().splitlines() if isinstance(mot_rows, Path) else mot_rows
    out: dict[int, list[tuple[float, float, float, float]]] = {}
    for line in lines:
        v = line.split(",")
        if len(v) >= 6:
            x, y, w, h = (float(t) for t in v[2:6])
            out.setdefault(int(v[0]), []).append((x - 1, y - 1, w, h))
    return out


def _quiet(fn, *a):
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return fn(*a)


def prepare(scene: Path, out: Path, min_perimeter_px: float, force: bool) -> dict[str, object]:
    """Detections and the ``detect`` tracker's run of one scene (kept from an earlier run into
    ``out`` unless ``force``); the peers' job."""
    from pipeline.cli import main

    run = out / scene.name
    if force or not (run / "det" / "summary.json").is_file():
        _quiet(main, ["detect", str(scene), "--out", str(run / "det"), "--no-rrd", "--force"])
    if force or not (run / "detect" / "summary.json").is_file():
        args = ["track", str(scene), "--tracker", "detect", "--out", str(run / "detect")]
        _quiet(main, [*args, "--no-rrd", "--no-plots", "--force"])
    rows = _dets(run / "det" / "rois.csv", min_perimeter_px)
    (run / "dets.txt").write_text("\n".join(rows) + "\n")
    from pipeline.io.sequence import open_sequence

    truth = open_sequence(scene).truth.primary()
    for name, boxes in (
        ("detections-perfect-ids", _boxes(rows)),
        ("detect-perfect-ids", _boxes(run / "detect" / "tracks.csv")),
    ):
        (run / f"{name}.csv").write_text("\n".join(perfect_ids(boxes, truth)) + "\n")
    ones = [",".join([*r.split(",")[:6], "1"]) for r in rows]
    (run / "dets-one.txt").write_text("\n".join(ones) + "\n")
    frames = json.loads((run / "det" / "summary.json").read_text())["frames"]
    return {"run": run, "frames": frames}


def score(scene: Path, tracks: Path) -> dict[str, float]:
    from pipeline.eval import evaluate_files

    m = evaluate_files(scene, tracks, id_rule="assign")
    pur = m.get("purity")
    return {
        "idf1": float(m.get("idf1") or 0.0),
        "mota": float(m.get("mota") or 0.0),
        "hota": float(m.get("hota") or 0.0),
        "purity": float(pur["overall"]) if isinstance(pur, dict) else 0.0,
    }


def main(argv: list[str] | None = None) -> int:
    from pipeline.bench import random_scene_set
    from pipeline.config import load_config
    from pipeline.synthetic.family import parse_seed_range

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", required=True, help="A-B, e.g. 1500-1519")
    ap.add_argument("--targets", default="2-3", help="targets per scene (default 2-3)")
    ap.add_argument("--out", type=Path, default=Path("runs/mot-peers"))
    ap.add_argument("--peer-python", type=Path, default=ROOT / ".venv-mot" / "bin" / "python")
    ap.add_argument("--json", type=Path)
    ap.add_argument(
        "--force", action="store_true", help="detect and track again (after a code change)"
    )
    a = ap.parse_args(argv)
    if not a.peer_python.is_file():
        print(f"error: no peer environment at {a.peer_python} (make it: tools/mot_peer_venv.sh)")
        return 1
    lo, hi = (int(v) for v in a.targets.split("-")) if "-" in a.targets else (int(a.targets),) * 2
    scenes = random_scene_set(
        seeds=parse_seed_range(a.seeds), targets=(lo, hi), out=a.out / "scenes", progress=False
    )
    per = load_config(None, []).detect.association.min_perimeter_px
    jobs, runs = [], []
    for s in scenes:
        p = prepare(s, a.out / "runs", per, a.force)
        run = p["run"]
        assert isinstance(run, Path)
        runs.append((s, run))
        for kind in ("", "-one"):
            jobs.append(
                {
                    "dets": str(run / f"dets{kind}.txt"),
                    "frames": p["frames"],
                    "out": {t: str(run / f"{t}{kind}.csv") for t in PEERS},
                }
            )
    (a.out / "jobs.json").write_text(json.dumps(jobs))
    done = subprocess.run(
        [str(a.peer_python), str(ROOT / "tools" / "mot_peer_worker.py"), str(a.out / "jobs.json")],
        capture_output=True,
        text=True,
        check=True,
    )
    peer_info = json.loads(done.stdout.strip().splitlines()[-1])
    names = ["detect"] + [f"{t}{k}" for t in PEERS for k in ("", "-one")]
    names += ["detect-perfect-ids", "detections-perfect-ids"]
    table: dict[str, list[dict[str, float]]] = {n: [] for n in names}
    for s, run in runs:
        table["detect"].append(score(s, run / "detect" / "tracks.csv"))
        for n in names[1:]:
            table[n].append(score(s, run / f"{n}.csv"))
    print(
        f"{len(runs)} scenes (seeds {a.seeds}, {a.targets} targets); peers: trackers "
        f"{peer_info['versions']['trackers']}, supervision {peer_info['versions']['supervision']}"
        "; '-one': every detection scored 1; '-perfect-ids': the detect tracker's boxes and the "
        "detections with the ids of the truth they overlap (the identity ceiling)"
    )
    print("| tracker | IDF1 mean | IDF1 p10 | IDF1 worst | MOTA | HOTA | purity |")
    print("|---|---|---|---|---|---|---|")
    summary = {}
    for n, rows in table.items():
        v = {k: np.array([r[k] for r in rows]) for k in rows[0]}
        summary[n] = {k: float(x.mean()) for k, x in v.items()}
        summary[n]["idf1_p10"] = float(np.percentile(v["idf1"], 10))
        summary[n]["idf1_worst"] = float(v["idf1"].min())
        d = summary[n]
        print(
            f"| {n} | {d['idf1']:.3f} | {d['idf1_p10']:.3f} | {d['idf1_worst']:.3f} | "
            f"{d['mota']:.3f} | {d['hota']:.3f} | {d['purity']:.3f} |"
        )
    if a.json:
        result = {"seeds": a.seeds, "trackers": summary, **peer_info}
        a.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
