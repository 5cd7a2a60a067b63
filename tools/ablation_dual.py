"""Ablation of the dual tracker: the paper's configuration, the full tracker, and each addition off
in turn.

Usage::

    python tools/ablation_dual.py [--split dev|test] [--count N] [--multi M] [--named] [--out DIR]
    [--variants a,b,...]

Runs ``dual`` with every variant on the first ``--count`` single-target random scenes of the
split (``dev`` to decide, ``test`` to report), with ``--multi`` on the first ``M`` scenes of 2-3
targets, and with ``--named`` on the eight named synthetic scenes (seed 0), on one thread, and
prints a Markdown table of mean P@20 / AUC, the 10th percentile of P@20 and the median tracking
rate per variant (for the scenes of several targets: mean IDF1, purity, purity on the frames
where each target is at least 25 % visible, and the 10th percentile of IDF1), then how many
scenes each variant moves against the first by more than 0.02 (AUC, or IDF1), then the mean
per-stage time per frame of the full tracker. ``paper`` is ``data/dual-paper.toml``;
``+groups`` puts the merge handling (eq. 10-11) in.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "data" / "dual-paper.toml"

VARIANTS: dict[str, list[str]] = {
    "full": [],
    "-appearance": ["dual.appearance=none"],
    "-redetect": ["dual.redetect=none"],
    "-extent": ["dual.extent=none"],
    "-filter-colour": ["dual.appearance.colour=false"],
    "-filter-visible-gradients": ["dual.appearance.visible_gradients=false"],
    "-filter-ir": ["dual.appearance.infrared=false"],
    "-filter-balance": ["dual.appearance.balance_groups=false"],
    "-filter-scale": ["dual.appearance.scale_filter=false"],
    "-contour-checks": ["dual.contour.checks=false"],
    "-channel-weighting": [
        "dual.colour.dark_gating=false",
        "dual.contour.trust_faded=true",
        "dual.contour.start_at=meanshift",
    ],
    "-motion-prior": ["dual.motion.search_from=last-position", "dual.contour.start_at=meanshift"],
    "-warm-start": ["dual.contour.warm_start=false"],
    "-closing": ["dual.contour.closing_fraction=0"],
    "-empty-retry": ["dual.contour.retry_empty_frames=1"],
    "+groups": ["dual.groups=default"],
    "paper": [],  # data/dual-paper.toml
}


def _p10(xs: list[float]) -> float:
    import numpy as np

    return float(np.percentile(xs, 10)) if xs else float("nan")


def _moved(a: dict[str, float], b: dict[str, float], by: float) -> list[str]:
    """The scenes whose figure differs between ``a`` and ``b`` by more than ``by``, the largest
    change first, each as ``name +0.123``."""
    diffs = sorted(((b[k] - a[k], k) for k in a if k in b), key=lambda d: -abs(d[0]))
    return [f"{k} {d:+.3f}" for d, k in diffs if abs(d) > by]


def main() -> None:
    import cv2

    from pipeline.bench import random_scene_set, run_bench
    from pipeline.synthetic import ONE_TARGET_SCENES, synthesize

    ap = argparse.ArgumentParser()
    ap.add_argument("--split", choices=("dev", "test"), default="dev")
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--multi", type=int, default=0, help="also M scenes of 2-3 targets")
    ap.add_argument("--named", action="store_true", help="also the eight named scenes (seed 0)")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    a = ap.parse_args()
    cv2.setNumThreads(1)
    variants = [v for v in a.variants.split(",") if v]
    for v in variants:
        if v not in VARIANTS:
            raise SystemExit(f"unknown variant {v!r}; known: {', '.join(VARIANTS)}")
    with tempfile.TemporaryDirectory() as tmp:
        root = a.out or Path(tmp)
        sets_of = {
            "random": random_scene_set(a.count, a.split, targets=(1, 1), out=root / "scenes")
        }
        if a.multi > 0:
            sets_of["multi"] = random_scene_set(
                a.multi, a.split, targets=(2, 3), out=root / "scenes"
            )
        if a.named:
            named = []
            for sc in ONE_TARGET_SCENES:
                d = root / "named" / sc
                if not d.exists():
                    synthesize(sc, d, seed=0)
                named.append(d)
            sets_of["named"] = named
        table: dict[str, dict[str, tuple[float, float, float, float]]] = {}
        ids: dict[str, tuple[float, float, float, float]] = {}
        per_scene: dict[str, dict[str, float]] = {}
        stages: dict[str, float] = {}
        frames = 0
        for v in variants:
            cfg = PAPER if v == "paper" else None
            for what, dirs in sets_of.items():
                rows = [
                    r
                    for r in run_bench(
                        dirs,
                        ["dual"],
                        out=root / "runs" / v / what,
                        sets=VARIANTS[v],
                        config_path=cfg,
                    )
                    if "p20" in r
                ]
                p20 = [float(r["p20"]) for r in rows]
                auc = [float(r["auc"]) for r in rows]
                fps = [float(r["fps_tracking"]) for r in rows]
                table.setdefault(v, {})[what] = (
                    statistics.mean(p20),
                    statistics.mean(auc),
                    _p10(p20),
                    statistics.median(fps),
                )
                key = "idf1" if what == "multi" else "auc"
                for r in rows:
                    per_scene.setdefault(v, {})[f"{what}/{r['sequence']}"] = float(r[key])
                if what == "multi":
                    idf1 = [float(r["idf1"]) for r in rows]
                    ids[v] = (
                        statistics.mean(idf1),
                        statistics.mean(float(r["purity"]) for r in rows),
                        statistics.mean(float(r["purity_visible"]) for r in rows),
                        _p10(idf1),
                    )
                if v == "full":
                    for r in rows:
                        frames += int(r["frames"])
                        for k, s in dict(r["stage_seconds"]).items():
                            stages[k] = stages.get(k, 0.0) + float(s)
        head = "| variant |" + "".join(
            f" {w}: P@20 / AUC (p10 P@20) | {w}: fps |" for w in sets_of
        )
        print(
            f"dual on {a.count} single-target {a.split} scenes"
            + (f", {a.multi} of 2-3 targets" if a.multi > 0 else "")
            + (" and the eight named scenes" if a.named else "")
        )
        print()
        print(head)
        print("|---|" + "---|---|" * len(sets_of))
        for v, per in table.items():
            cells = "".join(
                f" {p:.3f} / {u:.3f} ({q:.3f}) | {f:.0f} |"
                for p, u, q, f in (per[w] for w in sets_of)
            )
            print(f"| {v} |{cells}")
        if ids:
            print()
            print("| variant | 2-3 targets: IDF1 | purity | purity (visible) | p10 IDF1 |")
            print("|---|---|---|---|---|")
            for v, (f1, pu, pv, q) in ids.items():
                print(f"| {v} | {f1:.4f} | {pu:.4f} | {pv:.4f} | {q:.3f} |")
        first = variants[0]
        if len(variants) > 1:
            print()
            print(
                f"scenes moved by more than 0.02 (AUC; IDF1 with several targets) against {first}:"
            )
            for v in variants[1:]:
                moved = _moved(per_scene[first], per_scene[v], 0.02)
                more = ", ..." if len(moved) > 6 else ""
                print(f"- {v}: {len(moved)} ({', '.join(moved[:6])}{more})")
        if frames:
            print()
            print(
                "per-stage time of the full tracker, ms per frame: "
                + ", ".join(
                    f"{k} {1e3 * s / frames:.2f}"
                    for k, s in stages.items()
                    if k not in ("decode", "sinks", "tracker")
                )
            )


if __name__ == "__main__":
    main()
