"""Synthetic registered visible + IR sequences with exact ground truth.

``synthesize(name, out_dir, seed)`` writes one sequence folder in the RGBT234 layout:
``visible/00001v.jpg``, ``infrared/00001i.jpg``, ``visible.txt`` and ``infrared.txt``
(``x,y,w,h`` per frame, 0-based continuous px; ``0,0,0,0`` when the target is out of
the frame) and ``init.txt`` for one target, or a MOTChallenge ``gt.txt``
(``frame,id,x,y,w,h,1,1,visibility``, 1-based as MOTChallenge files are) for several;
plus ``scene.json`` (scenario, seed, size, per-target visibility per frame, notes).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np

from pipeline.errors import InputError
from pipeline.synthetic.scenarios import SCENARIO_BUILDERS
from pipeline.synthetic.scene import Renderer, Scene

SCENARIOS: dict[str, Scene] = {name: build() for name, build in SCENARIO_BUILDERS.items()}
JPEG_QUALITY = 92

# The challenge attributes of each scenario, in RGBT234's codes (NO no occlusion, PO partial
# occlusion, HO heavy occlusion, LI low illumination, TC thermal crossover, FM fast motion,
# SV scale variation, BC background clutter), written to scene.json for per-attribute reports.
ATTRIBUTES: dict[str, tuple[str, ...]] = {
    "dusk": ("NO", "LI"), "shadows": ("NO", "BC"), "approach": ("NO", "SV"), "lookalike": ("NO", "BC"),
    "hot-distractor": ("NO", "BC"), "crossover": ("NO", "TC"), "occluder": ("HO",), "fast": ("NO", "FM"),
    "crossing2": ("HO",), "crossing3": ("HO", "SV"), "meet-part": ("PO", "BC"), "group3": ("HO",),
    "occluded-static": ("HO", "BC"), "occluded-moving": ("HO",), "pole-fast": ("HO", "FM"),
}


def _ranges(mask: np.ndarray) -> list[list[int]]:
    """1-based inclusive frame ranges where ``mask`` is True."""
    out, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        if not m and start is not None:
            out.append([start + 1, i])
            start = None
    if start is not None:
        out.append([start + 1, len(mask)])
    return out


def synthesize(name: str, out_dir: str | Path, seed: int = 0, force: bool = False, progress: bool | None = None) -> Path:
    """Render scenario ``name`` into ``out_dir`` (the sequence folder); returns the folder."""
    if name not in SCENARIOS:
        raise InputError(f"unknown scenario {name!r}; available: {', '.join(SCENARIOS)}")
    out = Path(out_dir)
    if out.exists() and any(out.iterdir()):
        if not force:
            raise InputError(f"{out} already exists and is not empty; pass --force to overwrite it")
        shutil.rmtree(out)
    scene = SCENARIOS[name]
    (out / "visible").mkdir(parents=True, exist_ok=True)
    (out / "infrared").mkdir(parents=True, exist_ok=True)
    renderer = Renderer(scene, seed)
    ids = sorted({a.target_id for a in scene.actors if a.target_id > 0})
    n = scene.n_frames
    boxes = {i: np.full((n, 4), np.nan) for i in ids}
    vis = {i: np.zeros(n) for i in ids}
    from pipeline.progress import Progress

    with Progress(n, f"synth {name}", enabled=progress) as bar:
        for t in range(1, n + 1):
            v, ir, truth = renderer.render(t)
            cv2.imwrite(str(out / "visible" / f"{t:05d}v.jpg"), v, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            cv2.imwrite(str(out / "infrared" / f"{t:05d}i.jpg"), ir, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            for tid, (box, visibility) in truth.items():
                if box is not None:
                    boxes[tid][t - 1] = box
                vis[tid][t - 1] = visibility
            bar.update(1)
    if len(ids) == 1:
        b = boxes[ids[0]]
        lines = ["0,0,0,0" if np.isnan(r).any() else ",".join(f"{x:.3f}" for x in r) for r in b]
        for fname in ("visible.txt", "infrared.txt"):
            (out / fname).write_text("\n".join(lines) + "\n")
        (out / "init.txt").write_text(lines[0] + "\n")
    else:
        rows = []
        for t in range(n):
            for tid in ids:
                r = boxes[tid][t]
                if np.isnan(r).any():
                    continue
                rows.append(f"{t + 1},{tid},{r[0] + 1:.3f},{r[1] + 1:.3f},{r[2]:.3f},{r[3]:.3f},1,1,{vis[tid][t]:.3f}")
        (out / "gt.txt").write_text("\n".join(rows) + "\n")
    meta = {
        "scenario": name,
        "description": scene.description,
        "seed": seed,
        "width": scene.width,
        "height": scene.height,
        "frames": n,
        "targets": [{"id": i, "kind": next(a.kind for a in scene.actors if a.target_id == i)} for i in ids],
        "distractors": [a.name or a.kind for a in scene.actors if a.target_id == 0],
        "occluded_frames": {str(i): _ranges(vis[i] < 0.5) for i in ids},
        "hidden_frames": {str(i): _ranges(vis[i] < 0.05) for i in ids},
        "absent_frames": {str(i): _ranges(np.isnan(boxes[i]).any(axis=1)) for i in ids},
        "visibility": {str(i): [round(float(x), 3) for x in vis[i]] for i in ids},
        "attributes": list(ATTRIBUTES.get(name, ("NO",))),
        "notes": scene.notes,
    }
    (out / "scene.json").write_text(json.dumps(meta, indent=1) + "\n")
    return out


__all__ = ["SCENARIOS", "synthesize"]
