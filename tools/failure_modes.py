"""Where a tracker misses the truth on random scenes, and why: its failed target-frames by cause.

Usage: python tools/failure_modes.py RUN_ROOT [--tracker dual] [--worst 10]

``RUN_ROOT`` is a ``dualtrack bench --random N --out RUN_ROOT`` folder (``scenes/`` and
``runs/<tracker>/<scene>/targets.csv``). Every scene is drawn again from its seed and rendered
once more (its ``scene.json`` names the seed and the generator options), which gives the boxes
of the moving objects that are not targets, and each frame of each target whose output box has
IoU < 0.5 with the truth is put in the first class that applies:

``hidden``
    the target's visibility (share of its own pixels nothing covers) is under 0.25: no tracker
    sees it, a coast is all there is;
``on-other``
    the output box overlaps another target or a distractor (IoU >= 0.3) more than the target:
    an identity taken over;
``lost``
    no output box (status ``lost``) while the target is in view;
``coasting``
    an occluded status (the tracker knows it has no measurement) while the target is in view;
``size``
    the centre is within 20 px of the truth's, but the box's size is wrong;
``drift``
    anything else: the tracker measures the target somewhere it is not.

Prints one table row per scene (the worst ``--worst`` first) and the totals, as shares of all
target-frames with truth.
"""

from __future__ import annotations

import argparse
import csv
import json
from collections import Counter
from pathlib import Path

import numpy as np

from pipeline.synthetic.family import draw_scene
from pipeline.synthetic.scene import Renderer

CLASSES = ("hidden", "on-other", "lost", "coasting", "size", "drift")
Box = tuple[float, float, float, float]


def iou(a: Box, b: Box) -> float:
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def centre_distance(a: Box, b: Box) -> float:
    return float(np.hypot(a[0] + a[2] / 2 - b[0] - b[2] / 2, a[1] + a[3] / 2 - b[1] - b[3] / 2))


def scene_failures(scene_dir: Path, run_dir: Path) -> tuple[Counter, int]:
    """(failed target-frames per class, target-frames with truth) of one run."""
    meta = json.loads((scene_dir / "scene.json").read_text())
    gen = meta.get("generator") or {}
    targets = tuple(gen["targets"]) if gen.get("targets") else None
    size = tuple(gen.get("size") or (meta["width"], meta["height"]))
    frames = int(gen.get("frames") or meta["frames"])
    drawn = draw_scene(int(meta["seed"]), targets, int(size[0]), int(size[1]), frames)
    renderer = Renderer(drawn.scene, drawn.render_seed)
    out: dict[tuple[int, int], tuple[str, tuple[float, float, float, float]]] = {}
    with open(run_dir / "targets.csv") as fh:
        for r in csv.DictReader(fh):
            box = tuple(float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))
            out[(int(r["frame"]), int(r["id"]))] = (r["status"], box)
    counts: Counter = Counter()
    total = 0
    for t in range(1, drawn.scene.n_frames + 1):
        f = renderer.render_frame(t)
        others = [b for b in (f.others or {}).values() if b is not None]
        for tid, truth in f.truth_visible.items():
            if truth is None:
                continue
            total += 1
            status, box = out.get((t, tid), ("lost", (0.0, 0.0, 0.0, 0.0)))
            shown = status != "lost"
            if shown and iou(box, truth) >= 0.5:
                continue
            rivals = [b for j, b in f.truth_visible.items() if j != tid and b is not None] + others
            if f.visibility.get(tid, 0.0) < 0.25:
                counts["hidden"] += 1
            elif shown and any(
                iou(box, b) >= 0.3 and iou(box, b) > iou(box, truth) for b in rivals
            ):
                counts["on-other"] += 1
            elif not shown:
                counts["lost"] += 1
            elif status.startswith("occluded"):
                counts["coasting"] += 1
            elif centre_distance(box, truth) <= 20:
                counts["size"] += 1
            else:
                counts["drift"] += 1
    return counts, total


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", type=Path)
    ap.add_argument("--tracker", default="dual")
    ap.add_argument("--worst", type=int, default=10)
    a = ap.parse_args(argv)
    rows = []
    grand: Counter = Counter()
    n_all = 0
    for scene_dir in sorted((a.root / "scenes").iterdir()):
        run_dir = a.root / "runs" / a.tracker / scene_dir.name
        if not (run_dir / "targets.csv").is_file():
            continue
        c, n = scene_failures(scene_dir, run_dir)
        grand.update(c)
        n_all += n
        rows.append((sum(c.values()) / max(n, 1), scene_dir.name, c, n))
    rows.sort(reverse=True)
    print("| scene | failed | " + " | ".join(CLASSES) + " |")
    print("|---|---|" + "---|" * len(CLASSES))
    for share, name, c, n in rows[: a.worst]:
        print(f"| {name} | {share:.3f} | " + " | ".join(f"{c[k] / n:.3f}" for k in CLASSES) + " |")
    print(
        f"| all ({len(rows)} scenes) | {sum(grand.values()) / max(n_all, 1):.3f} | "
        + " | ".join(f"{grand[k] / max(n_all, 1):.3f}" for k in CLASSES)
        + " |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
