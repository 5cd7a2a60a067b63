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
    "dusk": ("NO", "LI"),
    "shadows": ("NO", "BC"),
    "approach": ("NO", "SV"),
    "lookalike": ("NO", "BC"),
    "hot-distractor": ("NO", "BC"),
    "crossover": ("NO", "TC"),
    "occluder": ("HO",),
    "fast": ("NO", "FM"),
    "crossing2": ("HO",),
    "crossing3": ("HO", "SV"),
    "meet-part": ("PO", "BC"),
    "group3": ("HO",),
    "occluded-static": ("HO", "BC"),
    "occluded-moving": ("HO",),
    "pole-fast": ("HO", "FM"),
}

ONE_TARGET_SCENES: tuple[str, ...] = (
    "shadows",
    "dusk",
    "approach",
    "lookalike",
    "hot-distractor",
    "crossover",
    "occluder",
    "fast",
)
"""The eight one-target named scenes, one challenge each: the set of the speed tables
(``dualtrack bench``, ``tools/benchmarks.py``, ``tools/profile_tracker.py``) and the ablations."""

SCENE_CODES = {
    "shadow": "BC",
    "darkness": "LI",
    "clutter": "BC",
    "crossover": "TC",
    "out-of-view": "OV",
    "scale-change": "SV",
    "fast-motion": "FM",
}
"""The RGBT234 (LasHeR: OV) code of each of the random family's per-frame flags: a random scene's
``attributes`` are in the same codes as the named scenes', so that a report has one row per
challenge (occlusion is PO or HO by how deep it goes)."""


def scene_codes(present: list[str], vis: dict[int, np.ndarray], min_frames: int) -> list[str]:
    """A random scene's attributes in RGBT234's codes, from the per-frame flags it carries:
    ``HO`` when some target is under a quarter visible for ``min_frames`` frames, else ``PO``
    with the occlusion flag, else ``NO``; then the code of every other flag.

    Examples
    --------
    >>> import numpy as np
    >>> scene_codes(["occlusion", "shadow", "clutter"], {1: np.full(9, 0.5)}, 5)
    ['PO', 'BC']
    """
    heavy = any(int((v < 0.25).sum()) >= min_frames for v in vis.values())
    codes = ["HO" if heavy else "PO"] if "occlusion" in present else ["NO"]
    for a in present:
        c = SCENE_CODES.get(a)
        if c is not None and c not in codes:
            codes.append(c)
    return codes


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


def _prepare(out_dir: str | Path, force: bool) -> Path:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} exists and is not a folder")
    if out.exists() and any(out.iterdir()):
        if not force:
            raise InputError(
                f"{out} already exists and is not empty; pass --force to overwrite it"
            )
        shutil.rmtree(out)
    (out / "visible").mkdir(parents=True, exist_ok=True)
    (out / "infrared").mkdir(parents=True, exist_ok=True)
    return out


def _box_lines(b: np.ndarray) -> list[str]:
    return ["0,0,0,0" if np.isnan(r).any() else ",".join(f"{x:.3f}" for x in r) for r in b]


DISTRACTOR_ID_BASE = 1000
"""Distractor rows of a random scene's ``gt.txt`` have ids ``DISTRACTOR_ID_BASE + actor index``."""


def _write_truth(
    out: Path,
    ids: list[int],
    boxes: dict[str, dict[int, np.ndarray]],
    vis: dict[int, np.ndarray],
    distractors: dict[int, np.ndarray] | None = None,
) -> None:
    """``visible.txt``/``infrared.txt``/``init.txt`` for one target, a MOT ``gt.txt`` (visible
    truth) for several.

    ``distractors`` (id -> (N, 4) visible boxes of moving objects that are not targets) become
    ``gt.txt`` rows with flag 0 and class 8 (MOTChallenge's "distractor"): not truth, and a
    track box on one is neither a true nor a false positive (``parse_mot_truth``).
    """
    n = next(iter(boxes["visible"].values())).shape[0]
    if len(ids) == 1:
        for ch, fname in (("visible", "visible.txt"), ("infrared", "infrared.txt")):
            (out / fname).write_text("\n".join(_box_lines(boxes[ch][ids[0]])) + "\n")
        (out / "init.txt").write_text(_box_lines(boxes["visible"][ids[0]])[0] + "\n")
        return
    rows = []
    for t in range(n):
        for tid in ids:
            r = boxes["visible"][tid][t]
            if np.isnan(r).any():
                continue
            x, y = r[0] + 1, r[1] + 1
            rows.append(
                f"{t + 1},{tid},{x:.3f},{y:.3f},{r[2]:.3f},{r[3]:.3f},1,1,{vis[tid][t]:.3f}"
            )
        for did, b in (distractors or {}).items():
            r = b[t]
            if not np.isnan(r).any():
                rows.append(
                    f"{t + 1},{did},{r[0] + 1:.3f},{r[1] + 1:.3f},{r[2]:.3f},{r[3]:.3f},0,8,1.000"
                )
    (out / "gt.txt").write_text("\n".join(rows) + "\n")


def _visibility_meta(
    ids: list[int], boxes: dict[int, np.ndarray], vis: dict[int, np.ndarray]
) -> dict[str, object]:
    return {
        "occluded_frames": {str(i): _ranges(vis[i] < 0.5) for i in ids},
        "hidden_frames": {str(i): _ranges(vis[i] < 0.05) for i in ids},
        "absent_frames": {str(i): _ranges(np.isnan(boxes[i]).any(axis=1)) for i in ids},
        "visibility": {str(i): [round(float(x), 3) for x in vis[i]] for i in ids},
    }


def synthesize(
    name: str | Scene,
    out_dir: str | Path,
    seed: int = 0,
    force: bool = False,
    progress: bool | None = None,
) -> Path:
    """Render the named scenario ``name`` into ``out_dir``, a sequence folder with exact truth.

    Parameters
    ----------
    name : str or Scene
        One of ``dualtrack synth --list`` (``crossing2``, ``shadows``, ...), or a
        :class:`~pipeline.synthetic.scene.Scene` of your own (actors on keyframed paths, see
        :func:`~pipeline.synthetic.scenarios.keyframes`).
    out_dir : str or Path
        The sequence folder to write (RGBT234 layout: ``visible/``, ``infrared/``, the truth
        files, ``scene.json``; a MOT ``gt.txt`` for several targets).
    seed : int
        The sensor noise and jitter, >= 0; default 0.
    force : bool
        Overwrite a non-empty ``out_dir``.
    progress : bool, optional
        A progress bar (default: on a terminal only).

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    InputError
        An unknown scenario, a negative seed, or a non-empty ``out_dir`` without ``force``.

    Examples
    --------
    >>> import tempfile
    >>> from pipeline import open_sequence, synthesize
    >>> seq = open_sequence(synthesize("pole-fast", tempfile.mkdtemp() + "/s", progress=False))
    >>> seq.channels, seq.n_frames
    (('visible', 'infrared'), 32)
    """
    if isinstance(name, Scene):
        scene, name = name, name.name
    elif name in SCENARIOS:
        scene = SCENARIOS[name]
    else:
        raise InputError(f"unknown scenario {name!r}; available: random, {', '.join(SCENARIOS)}")
    if not (isinstance(seed, int) and seed >= 0):
        raise InputError(f"--seed must be a non-negative integer; got {seed!r}")
    out = _prepare(out_dir, force)
    renderer = Renderer(scene, seed)
    ids = sorted({a.target_id for a in scene.actors if a.target_id > 0})
    n = scene.n_frames
    boxes = {i: np.full((n, 4), np.nan) for i in ids}
    vis = {i: np.zeros(n) for i in ids}
    from pipeline.progress import Progress

    with Progress(n, f"synth {name}", enabled=progress) as bar:
        for t in range(1, n + 1):
            v, ir, truth = renderer.render(t)
            cv2.imwrite(
                str(out / "visible" / f"{t:05d}v.jpg"), v, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]
            )
            cv2.imwrite(
                str(out / "infrared" / f"{t:05d}i.jpg"),
                ir,
                [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY],
            )
            for tid, (box, visibility) in truth.items():
                if box is not None:
                    boxes[tid][t - 1] = box
                vis[tid][t - 1] = visibility
            bar.update(1)
    _write_truth(out, ids, {"visible": boxes, "infrared": boxes}, vis)
    meta = {
        "scenario": name,
        "description": scene.description,
        "seed": seed,
        "width": scene.width,
        "height": scene.height,
        "frames": n,
        "targets": [
            {"id": i, "kind": next(a.kind for a in scene.actors if a.target_id == i)} for i in ids
        ],
        "distractors": [a.name or a.kind for a in scene.actors if a.target_id == 0],
        **_visibility_meta(ids, boxes, vis),
        "attributes": list(ATTRIBUTES.get(name, ("NO",))),
        "notes": scene.notes,
    }
    (out / "scene.json").write_text(json.dumps(meta, indent=1) + "\n")
    return out


IR16_GAIN = 200.0
IR16_OFFSET = 3000.0
"""16-bit IR counts = IR16_OFFSET + IR16_GAIN x grey level (before the 8-bit quantisation): a
14-bit-like range."""


def synthesize_random(
    out_dir: str | Path,
    seed: int,
    targets: tuple[int, int] | int | None = None,
    size: tuple[int, int] = (320, 240),
    frames: int = 200,
    ir16: bool = False,
    force: bool = False,
    progress: bool | None = None,
) -> Path:
    """Draw the random scene of ``seed`` (:mod:`pipeline.synthetic.family`) and write it into
    ``out_dir``.

    The folder is in the RGBT234 layout: ``visible/*.jpg``, ``infrared/*.jpg`` (16-bit
    ``*.png`` with ``ir16``), per-channel truth ``visible.txt`` / ``infrared.txt`` (they
    differ by the drawn misregistration) and ``init.txt`` for one target or a MOT
    ``gt.txt`` of the visible truth for several (with the moving objects that are not targets
    as distractor rows, flag 0 and class 8), and ``scene.json`` with every drawn
    parameter, the per-frame challenge flags per target (``frame_attributes``: 1-based
    inclusive frame ranges) and the scene-level ``attributes`` list.

    Parameters
    ----------
    out_dir : str or Path
        The sequence folder to write.
    seed : int
        The scene, >= 0: seeds 0-999 are the development range (tune there), 1000-1999 the
        test range (only ever scored).
    targets : int or (int, int), optional
        The number of targets, or a range to draw it from; default the family's own draw.
    size : (int, int)
        Frame width and height, px; default (320, 240).
    frames : int
        Frames to render, >= 30; default 200.
    ir16 : bool
        Write 16-bit infrared PNGs instead of 8-bit JPEGs.
    force : bool
        Overwrite a non-empty ``out_dir``.
    progress : bool, optional
        A progress bar (default: on a terminal only).

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    InputError
        A negative seed, a bad target count or size, or a non-empty ``out_dir`` without ``force``.

    Examples
    --------
    >>> import json, tempfile
    >>> from pipeline import synthesize_random
    >>> d = synthesize_random(tempfile.mkdtemp() + "/s", seed=5, targets=2, frames=30,
    ...                       progress=False)
    >>> meta = json.loads((d / "scene.json").read_text())
    >>> meta["seed"], len(meta["targets"]), (d / "gt.txt").is_file()
    (5, 2, True)
    """
    from pipeline.progress import Progress
    from pipeline.synthetic.family import ATTRIBUTES as FRAME_ATTRIBUTES
    from pipeline.synthetic.family import (
        DISTRACTOR_ROLES,
        MIN_ATTRIBUTE_FRAMES,
        draw_scene,
        frame_attributes,
    )

    if not (isinstance(seed, int) and seed >= 0):
        raise InputError(f"--seed must be a non-negative integer; got {seed!r}")
    try:
        drawn = draw_scene(seed, targets, size[0], size[1], frames)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    out = _prepare(out_dir, force)
    scene = drawn.scene
    renderer = Renderer(scene, drawn.render_seed)
    ids = sorted({a.target_id for a in scene.actors if a.target_id > 0})
    n = scene.n_frames
    boxes = {ch: {i: np.full((n, 4), np.nan) for i in ids} for ch in ("visible", "infrared")}
    vis = {i: np.zeros(n) for i in ids}
    movers = [i for i, role in drawn.roles.items() if role in DISTRACTOR_ROLES]
    others = {DISTRACTOR_ID_BASE + i: np.full((n, 4), np.nan) for i in movers}
    flags = {i: {a: np.zeros(n, bool) for a in FRAME_ATTRIBUTES} for i in ids}
    first_size: dict[int, float] = {}
    last_center: dict[int, tuple[float, float]] = {}
    qv, qi = drawn.jpeg_quality
    with Progress(n, f"synth random {seed}", enabled=progress) as bar:
        for t in range(1, n + 1):
            f = renderer.render_frame(t)
            cv2.imwrite(
                str(out / "visible" / f"{t:05d}v.jpg"), f.visible, [cv2.IMWRITE_JPEG_QUALITY, qv]
            )
            if ir16:
                raw = np.clip(IR16_OFFSET + IR16_GAIN * f.infrared_float, 0, 65535).astype(
                    np.uint16
                )
                cv2.imwrite(str(out / "infrared" / f"{t:05d}i.png"), raw)
            else:
                cv2.imwrite(
                    str(out / "infrared" / f"{t:05d}i.jpg"),
                    f.infrared,
                    [cv2.IMWRITE_JPEG_QUALITY, qi],
                )
            for tid in ids:
                for ch, tb in (("visible", f.truth_visible), ("infrared", f.truth_infrared)):
                    if tb.get(tid) is not None:
                        boxes[ch][tid][t - 1] = tb[tid]
                vis[tid][t - 1] = f.visibility.get(tid, 0.0)
            for i in movers:
                ob = (f.others or {}).get(i)
                if ob is not None:
                    others[DISTRACTOR_ID_BASE + i][t - 1] = ob
            for tid, fl in frame_attributes(drawn, t, f, first_size, last_center).items():
                for a, v in fl.items():
                    flags[tid][a][t - 1] = v
            bar.update(1)
    _write_truth(out, ids, boxes, vis, others)
    present = [
        a
        for a in FRAME_ATTRIBUTES
        if any(int(flags[i][a].sum()) >= MIN_ATTRIBUTE_FRAMES for i in ids)
    ]
    meta = {
        "scenario": "random",
        "family": "random",
        "description": scene.description,
        "seed": seed,
        "width": scene.width,
        "height": scene.height,
        "frames": n,
        "ir16": ir16,
        "targets": [
            {"id": i, "kind": next(a.kind for a in scene.actors if a.target_id == i)} for i in ids
        ],
        "distractors": [a.name or a.kind for a in scene.actors if a.target_id == 0],
        **_visibility_meta(ids, boxes["visible"], vis),
        "attributes": scene_codes(present, vis, MIN_ATTRIBUTE_FRAMES),
        "frame_attributes": {
            str(i): {a: _ranges(flags[i][a]) for a in FRAME_ATTRIBUTES} for i in ids
        },
        "params": drawn.params,
        # the arguments the scene was drawn with: draw_scene(seed, **generator) draws it again
        "generator": {
            "targets": list(targets) if isinstance(targets, tuple) else targets,
            "size": [int(size[0]), int(size[1])],
            "frames": int(frames),
        },
    }
    (out / "scene.json").write_text(json.dumps(json_ready(meta), indent=1) + "\n")
    return out


def json_ready(x: object) -> object:
    """Numpy scalars and tuples in ``x`` made plain JSON values."""
    if isinstance(x, dict):
        return {str(k): json_ready(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_ready(v) for v in x]
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.floating | float):
        return round(float(x), 4)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


__all__ = ["SCENARIOS", "synthesize", "synthesize_random"]
