"""How well the detector's boxes cover the targets: coverage at IoU 0.5, fragments and oversize.

For each random scene (:mod:`pipeline.synthetic.family`), ``dualtrack detect`` writes the
detector's regions; the detections the ``detect`` tracker uses (accepted regions of at least
``detect.association.min_perimeter_px`` boundary, as ``tools/mot_peers.py`` hands them to the
peers) are compared with the truth (``gt.txt``). Every truth target-frame in view (visibility
>= ``--min-visibility``, default 0.25: a hidden target cannot be detected) is

``covered``
    a detection overlaps it at IoU >= 0.5;
``fragment``
    else, the detection sharing most pixels with it lies mostly on it (at least half of the
    detection) and covers under half of it: a torso without the legs, a head, a wheel;
``oversize``
    else, that detection holds at least half of the target but is too large for IoU 0.5; counted
    apart where it also holds at least half of another object (one region for two);
``off``
    else, a detection overlaps it, mostly elsewhere;
``missed``
    no detection overlaps it.

The scene's other moving objects (``gt.txt`` rows of confidence 0) are not targets: a region
holding a target and one of them is ``oversize`` with another object, and a detection of one
alone is left out of the precision. Also printed: the precision of the detections (share at
IoU >= 0.5 with a target's box in view) and the recall on isolated visible targets (visibility
>= 0.9, no other object's box touching theirs), also by the target's kind (``scene.json``:
person, cyclist, car), the per-scene distribution of the coverage
(mean, 10th percentile, worst) and the detector's ms a frame, in wall time and in its own CPU time
(its summary's: the wall time also holds what the run's reader and writer threads take). Usage::

    python tools/detection_quality.py --seeds 0-59 --out runs/detq          # development
    python tools/detection_quality.py --seeds 1000-1999:10 --out runs/detq  # test: every 10th

Scenes are generated into ``OUT/scenes`` unless there; detections of an earlier call are reused
(``--force`` detects again, after a code change). Development seeds are 0-999, test seeds
1000-1999 (score those once, when an issue closes; never tune on them).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # mot_peers, beside this file

CLASSES = ("covered", "fragment", "oversize", "off", "missed")
Box = tuple[float, float, float, float]


def _inter(a: Box, b: Box) -> float:
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    return ix * iy


def _iou(a: Box, b: Box) -> float:
    i = _inter(a, b)
    u = a[2] * a[3] + b[2] * b[3] - i
    return i / u if u > 0 else 0.0


def classify(target: Box, others: list[Box], dets: list[Box]) -> str:
    """The class of one truth box given the frame's detections and the other targets' boxes.

    Examples
    --------
    >>> t = (10.0, 10.0, 10.0, 20.0)
    >>> classify(t, [], [(10.0, 11.0, 10.0, 19.0)])
    'covered'
    >>> classify(t, [], [(10.0, 10.0, 10.0, 8.0)])  # the top 40 %
    'fragment'
    >>> classify(t, [(22.0, 10.0, 10.0, 20.0)], [(8.0, 8.0, 26.0, 24.0)])  # holds both
    'oversize-other'
    >>> classify(t, [], [(0.0, 0.0, 40.0, 40.0)])
    'oversize'
    >>> classify(t, [], [(18.0, 10.0, 20.0, 20.0)])  # mostly to the right of it
    'off'
    >>> classify(t, [], [(50.0, 50.0, 5.0, 5.0)])
    'missed'
    """
    if any(_iou(target, d) >= 0.5 for d in dets):
        return "covered"
    shared = [(_inter(target, d), d) for d in dets]
    shared = [(i, d) for i, d in shared if i > 0]
    if not shared:
        return "missed"
    i, d = max(shared, key=lambda x: x[0])
    area_t, area_d = target[2] * target[3], d[2] * d[3]
    if i >= 0.5 * area_d and i < 0.5 * area_t:
        return "fragment"
    if i >= 0.5 * area_t:
        holds_other = any(_inter(o, d) >= 0.5 * o[2] * o[3] for o in others)
        return "oversize-other" if holds_other else "oversize"
    return "off"


def _truth(scene: Path) -> dict[int, list[tuple[int, Box, float, bool]]]:
    """frame -> [(id, 0-based box, visibility, is a target)] of ``gt.txt`` (1-based MOT rows;
    rows of confidence 0 are the scene's other moving objects, its distractors)."""
    out: dict[int, list[tuple[int, Box, float, bool]]] = {}
    for line in (scene / "gt.txt").read_text().splitlines():
        v = line.split(",")
        if len(v) < 6:
            continue
        vis = float(v[8]) if len(v) > 8 else 1.0
        target = float(v[6]) != 0 if len(v) > 6 else True
        box = (float(v[2]) - 1, float(v[3]) - 1, float(v[4]), float(v[5]))
        out.setdefault(int(v[0]), []).append((int(v[1]), box, vis, target))
    return out


def _detections(rois: Path, min_perimeter_px: float) -> dict[int, list[Box]]:
    """frame -> 0-based boxes of the regions the ``detect`` tracker uses (as the peers get them,
    :func:`mot_peers.tracker_regions`)."""
    from mot_peers import tracker_regions

    out: dict[int, list[Box]] = {}
    for r in tracker_regions(rois, min_perimeter_px):
        box = tuple(float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))
        out.setdefault(int(r["frame"]), []).append(box)  # type: ignore[arg-type]
    return out


def score_scene(scene: Path, rois: Path, min_perimeter_px: float, min_vis: float) -> dict:
    """Counts of the classes, precision's and isolated recall's numerators and denominators."""
    truth, dets = _truth(scene), _detections(rois, min_perimeter_px)
    kinds = _kinds(scene)
    by_kind: dict[str, Counter[str]] = {}
    counts: Counter[str] = Counter()
    n_det = n_det_ok = n_iso = n_iso_ok = 0
    for frame, rows in truth.items():
        ds = dets.get(frame, [])
        shown = [(i, b, v, t) for i, b, v, t in rows if b[2] > 0 and b[3] > 0]
        in_view = [(i, b, v) for i, b, v, t in shown if t and v >= min_vis]
        for i, b, v in in_view:
            others = [o for j, o, _, _ in shown if j != i]  # targets and distractors
            c = classify(b, others, ds)
            counts[c] += 1
            if v >= 0.9 and not any(_inter(b, o) > 0 for o in others):
                n_iso += 1
                n_iso_ok += c == "covered"
                by_kind.setdefault(kinds.get(i, "target"), Counter())[c] += 1
        # a detection of a distractor is neither right nor wrong (MOT's ignored rows)
        ignored = [b for _, b, _, t in shown if not t]
        ds = [d for d in ds if not any(_iou(d, b) >= 0.5 for b in ignored)]
        n_det += len(ds)
        n_det_ok += sum(any(_iou(d, b) >= 0.5 for _, b, _ in in_view) for d in ds)
    for frame, ds in dets.items():
        if frame not in truth:
            n_det += len(ds)
    return {
        "counts": dict(counts),
        "detections": n_det,
        "detections_on_target": n_det_ok,
        "isolated": n_iso,
        "isolated_covered": n_iso_ok,
        "isolated_by_kind": {k: dict(v) for k, v in sorted(by_kind.items())},
    }


def _kinds(scene: Path) -> dict[int, str]:
    """Target id -> its kind (person, cyclist, car) from the scene's ``scene.json``, if any."""
    meta = scene / "scene.json"
    if not meta.is_file():
        return {}
    targets = json.loads(meta.read_text()).get("params", {}).get("targets", [])
    return {int(t["id"]): str(t["kind"]) for t in targets if "kind" in t and "id" in t}


def _job(args: tuple[str, str, float, float, bool, tuple[str, ...]]) -> dict:
    scene_s, run_s, per, min_vis, force, sets = args
    from pipeline.cli import main

    scene, run = Path(scene_s), Path(run_s)
    if force or not (run / "summary.json").is_file():
        extra = [a for s in sets for a in ("--set", s)]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            main(["detect", str(scene), "--out", str(run), "--no-rrd", "--force", *extra])
    summary = json.loads((run / "summary.json").read_text())
    r = score_scene(scene, run / "rois.csv", per, min_vis)
    r["scene"] = scene.name
    r["ms_per_frame"] = _ms_per_frame(summary)
    r["ms_per_frame_cpu"] = summary.get("ms_per_frame_cpu")
    return r


def _ms_per_frame(summary: dict) -> float | None:
    s, n = summary.get("stage_seconds") or {}, summary.get("frames") or 0
    total = s.get("detect", s.get("detection"))
    return 1000.0 * float(total) / n if total and n else None


def _seeds(text: str) -> range:
    """``A-B`` or ``A-B:STEP``."""
    span, _, step = text.partition(":")
    a, _, b = span.partition("-")
    return range(int(a), int(b or a) + 1, int(step or 1))


def main(argv: list[str] | None = None) -> int:
    from pipeline.bench import random_scene_set
    from pipeline.config import load_config

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", required=True, help="A-B or A-B:STEP, e.g. 1000-1999:10")
    ap.add_argument("--targets", default="2-3", help="targets per scene, K or A-B (default 2-3)")
    ap.add_argument("--out", type=Path, default=Path("runs/detection-quality"))
    ap.add_argument("--min-visibility", type=float, default=0.25)
    ap.add_argument(
        "--size", default="320x240", help="WxH of the generated scenes (default 320x240)"
    )
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--json", type=Path, help="also write the figures as JSON")
    ap.add_argument("--force", action="store_true", help="detect again (after a code change)")
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="PATH.PARAM=VALUE",
        help="a detector parameter, as dualtrack detect's --set (repeatable; use a new --out or "
        "--force, the detections of an earlier call are reused)",
    )
    a = ap.parse_args(argv)
    lo, hi = (int(v) for v in a.targets.split("-")) if "-" in a.targets else (int(a.targets),) * 2
    w, _, h = a.size.partition("x")
    scenes = random_scene_set(
        seeds=_seeds(a.seeds),
        targets=(lo, hi),
        out=a.out / "scenes",
        size=(int(w), int(h)),
        progress=False,
    )
    per = load_config(None, []).detect.association.min_perimeter_px
    jobs = [
        (str(s), str(a.out / "det" / s.name), per, a.min_visibility, a.force, tuple(a.set))
        for s in scenes
    ]
    with ProcessPoolExecutor(max_workers=max(a.jobs, 1)) as pool:
        results = list(pool.map(_job, jobs))
    report = summarise(results)
    print(table(report))
    if a.json:
        a.json.write_text(json.dumps({"scenes": results, "summary": report}, indent=1))
    return 0


def summarise(results: list[dict]) -> dict:
    """Pooled shares of the classes, precision, isolated recall, the per-scene coverage's
    distribution and the detector's median ms a frame."""
    total: Counter[str] = Counter()
    for r in results:
        total.update(r["counts"])
    n = sum(total.values())
    cov = [
        r["counts"].get("covered", 0) / max(sum(r["counts"].values()), 1)
        for r in results
        if r["counts"]
    ]
    det = sum(r["detections"] for r in results)
    iso = sum(r["isolated"] for r in results)
    kinds: dict[str, Counter[str]] = {}
    for r in results:
        for k, c in r.get("isolated_by_kind", {}).items():
            kinds.setdefault(k, Counter()).update(c)
    ms = [r["ms_per_frame"] for r in results if r.get("ms_per_frame")]
    cpu = [r["ms_per_frame_cpu"] for r in results if r.get("ms_per_frame_cpu")]
    return {
        "scenes": len(results),
        "target_frames": n,
        "shares": {c: total.get(c, 0) / n if n else 0.0 for c in (*CLASSES, "oversize-other")},
        "coverage_mean": float(np.mean(cov)) if cov else None,
        "coverage_p10": float(np.percentile(cov, 10)) if cov else None,
        "coverage_worst": float(min(cov)) if cov else None,
        "precision": sum(r["detections_on_target"] for r in results) / det if det else None,
        "isolated_recall": sum(r["isolated_covered"] for r in results) / iso if iso else None,
        "isolated_target_frames": iso,
        "isolated_by_kind": {
            k: {"target_frames": sum(c.values())}
            | {cls: c.get(cls, 0) / sum(c.values()) for cls in CLASSES}
            for k, c in sorted(kinds.items())
        },
        "ms_per_frame_median": float(np.median(ms)) if ms else None,
        "ms_per_frame_cpu_median": float(np.median(cpu)) if cpu else None,
    }


def table(s: dict) -> str:
    """The summary as a Markdown table (oversize pooled: with and without another target)."""
    sh = s["shares"]

    def f(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.3f}"

    oversize = sh["oversize"] + sh["oversize-other"]
    lines = [
        f"{s['scenes']} scenes, {s['target_frames']} truth target-frames in view",
        "",
        "| covered (IoU >= 0.5) | fragment | oversize (of it: holding another object) | off"
        " | missed |",
        "|---|---|---|---|---|",
        f"| {f(sh['covered'])} | {f(sh['fragment'])} | {f(oversize)} ({f(sh['oversize-other'])})"
        f" | {f(sh['off'])} | {f(sh['missed'])} |",
        "",
        f"coverage per scene: mean {f(s['coverage_mean'])}, 10th percentile "
        f"{f(s['coverage_p10'])}, worst {f(s['coverage_worst'])}",
        f"precision at IoU 0.5 {f(s['precision'])}; recall on isolated visible targets "
        f"{f(s['isolated_recall'])} ({s['isolated_target_frames']} target-frames); detector "
        f"{f(s['ms_per_frame_median'])} ms a frame, {f(s.get('ms_per_frame_cpu_median'))} ms of"
        " its own CPU time (medians over scenes)",
    ]
    kinds = s.get("isolated_by_kind") or {}
    if kinds:
        lines.append(
            "isolated visible targets by kind: "
            + "; ".join(
                f"{k} covered {f(v['covered'])} (fragment {f(v['fragment'])}, missed "
                f"{f(v['missed'])}; {v['target_frames']} target-frames)"
                for k, v in kinds.items()
            )
        )
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
