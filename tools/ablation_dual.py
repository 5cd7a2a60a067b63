"""Ablation of the dual tracker's beyond-the-paper steps on the synthetic scenes (issue 3, step 5).

Usage: python tools/ablation_dual.py [--out DIR] [--seed N] [--scenes a,b,...]

Renders the scenes (or reuses DIR/<scene>), runs ``dual`` with every variant on one
thread, and prints a Markdown table of P@20 / AUC per scene and variant, then the mean
per-stage time per frame of the full tracker. Variants: ``full`` (defaults), each step
switched off alone (``-warm-start``, ``-contour-checks``, ``-channel-weighting``,
``-motion-prior``, ``-closing``), and ``paper`` (all of them off).
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

VARIANTS = {
    "full": [],
    "-warm-start": ["contour.warm_start=false"],
    "-contour-checks": ["dual.contour_checks=false"],
    "-channel-weighting": ["dual.channel_weighting=false"],
    "-motion-prior": ["dual.motion_prior=false"],
    "-closing": ["contour.closing_fraction=0"],
    "paper": ["contour.warm_start=false", "dual.contour_checks=false", "dual.channel_weighting=false",
              "dual.motion_prior=false", "contour.closing_fraction=0"],
}
SCENES = ("shadows", "dusk", "approach", "lookalike", "hot-distractor", "crossover", "occluder", "fast")


def main() -> None:
    import cv2
    import numpy as np

    from pipeline.run import RunOptions, run_track
    from pipeline.synthetic import synthesize

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scenes", default=",".join(SCENES))
    a = ap.parse_args()
    cv2.setNumThreads(1)
    scenes = [s for s in a.scenes.split(",") if s]
    with tempfile.TemporaryDirectory() as tmp:
        root = a.out or Path(tmp)
        results: dict[str, dict[str, tuple[float, float]]] = {}
        stages: dict[str, float] = {}
        frames = 0
        for sc in scenes:
            d = root / sc
            if not d.exists():
                synthesize(sc, d, seed=a.seed)
            for name, sets in VARIANTS.items():
                r = run_track(d, RunOptions(tracker="dual", out_dir=root / "runs" / name / sc, rrd=False, plots=False,
                                            force=True, sets=sets))
                m = r.summary["metrics"]
                results.setdefault(name, {})[sc] = (m["p20"], m["auc"])
                if name == "full":
                    n = r.summary["frames"]
                    frames += n
                    for k, v in r.summary["stage_seconds"].items():
                        stages[k] = stages.get(k, 0.0) + v
        head = "| variant | " + " | ".join(scenes) + " | mean P@20 | mean AUC |"
        print(head)
        print("|" + "---|" * (len(scenes) + 3))
        for name, per in results.items():
            cells = [f"{per[s][0]:.2f} / {per[s][1]:.2f}" for s in scenes]
            mp = np.mean([per[s][0] for s in scenes])
            ma = np.mean([per[s][1] for s in scenes])
            print(f"| {name} | " + " | ".join(cells) + f" | {mp:.3f} | {ma:.3f} |")
        print()
        print("per-stage time of the full tracker, ms per frame: " + ", ".join(
            f"{k} {1e3 * v / frames:.2f}" for k, v in stages.items() if k not in ("decode", "sinks")))


if __name__ == "__main__":
    main()
