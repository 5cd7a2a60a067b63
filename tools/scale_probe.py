"""How well the correlation filter's scale search follows a target's size, on its own.

The dual tracker's filter (``pipeline.stages.appearance``) is trained on the first frame's truth
box and then, on every frame, asked for the target's size at the truth's centre (so that no
error of position enters), and blended with the frame at the size it found, as the tracker
does. What it finds is compared with the truth's height:

``change``
    the truth's height on the last frame over the first (1: no change of size);
``found``
    the filter's height over the truth's on the last frame (1: it followed);
``followed``
    the share of the truth's change of log-size that the filter's log-size took, by least
    squares over the frames (1: all of it, 0: it kept its first size; ``-`` where the truth's
    height never moves by 15 %);
``median err``
    the median over the frames of ``|log(found height / truth height)|``.

Sparse truth (VTUAV: every tenth frame) is interpolated linearly between annotated frames; frames
outside the truth, and frames whose truth box touches the frame's border (cut: its size is no
longer the target's), are skipped. One target per sequence (the first of the truth).

Usage::

    dualtrack synth random /tmp/dev --seeds 0-99 --targets 1
    python tools/scale_probe.py /tmp/dev/random-*
    python tools/scale_probe.py /tmp/dev/random-0760 --set scale_step=1.045 --set scale_count=17
    python tools/scale_probe.py ../shared/realdata/*/    # where it is beside the project
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.environ.setdefault("OMP_NUM_THREADS", "1")

from pipeline.config import load_config  # noqa: E402
from pipeline.errors import InputError  # noqa: E402
from pipeline.io.sequence import open_sequence  # noqa: E402
from pipeline.stages import appearance as app  # noqa: E402
from pipeline.types import BBox  # noqa: E402


def _config(sets: list[str]) -> app.AppearanceConfig:
    """The filter's defaults with ``name=value`` overrides of ``dual.appearance`` (coerced and
    range-checked as ``--set`` is)."""
    cfg = load_config(None, [f"dual.appearance.{s}" for s in sets]).dual.appearance
    if cfg is None:
        raise InputError("scale_probe: the probe needs the correlation filter")
    return cfg


def _dense(boxes: np.ndarray) -> np.ndarray:
    """``(N, 4)`` truth with NaN rows between annotated ones filled linearly; rows before the
    first or after the last annotated one stay NaN."""
    out = boxes.astype(np.float64).copy()
    ok = np.flatnonzero(np.all(np.isfinite(out), axis=1) & (out[:, 2] > 0) & (out[:, 3] > 0))
    if len(ok) < 2:
        return out
    idx = np.arange(ok[0], ok[-1] + 1)
    for k in range(4):
        out[idx, k] = np.interp(idx, ok, out[ok, k])
    return out


def _inside(box: BBox, width: int, height: int) -> bool:
    """The box lies in the frame, at least a pixel from every border."""
    return box.x >= 1 and box.y >= 1 and box.x + box.w <= width - 1 and box.y + box.h <= height - 1


def probe(path: str, cfg: app.AppearanceConfig) -> dict[str, float] | None:
    """The filter's size against the truth's over one sequence; None without truth."""
    seq = open_sequence(path)
    truth = seq.truth.primary()
    if not truth:
        return None
    gt = _dense(truth[min(truth)])
    found, true = [], []
    model, size = None, None
    for fr in seq.frames():
        g = gt[fr.index - 1] if fr.index - 1 < len(gt) else None
        if g is None or not np.all(np.isfinite(g)):
            continue
        box = BBox(*map(float, g))
        if not _inside(box, seq.width, seq.height):
            continue  # cut by the frame's border: its truth is no longer the target's size
        vis, ir = fr.visible, fr.infrared
        if model is None:
            model, size = app.train(vis, ir, box, cfg), (box.w, box.h)
            h0 = box.h
            continue
        d = app.detect(model, vis, ir, box.center, cfg, size=size, with_scale=True)
        size = d.size
        model = app.update(model, vis, ir, BBox.from_center(box.cx, box.cy, *size), cfg)
        found.append(size[1])
        true.append(box.h)
    if not found:
        return None
    lf, lt = np.log(np.array(found) / h0), np.log(np.array(true) / h0)
    den = float(lt @ lt)
    moved = float(np.max(np.abs(lt))) > math.log(1.15)
    return {
        "change": true[-1] / h0,
        "found": found[-1] / true[-1],
        "followed": float(lf @ lt) / den if moved else math.nan,
        "median_err": float(np.median(np.abs(lf - lt))),
    }


def _num(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="+", help="sequence folders with truth")
    ap.add_argument(
        "--set", action="append", default=[], help="a dual.appearance parameter, name=value"
    )
    a = ap.parse_args(argv)
    try:
        cfg = _config(a.set)
    except InputError as exc:
        raise SystemExit(f"scale_probe: {exc}") from None
    print("| sequence | change | found | followed | median err |")
    print("|---|---|---|---|---|")
    rows = []
    for p in a.sequences:
        if not Path(p).is_dir():
            raise SystemExit(f"scale_probe: not a sequence folder: {p}")
        try:
            r = probe(p, cfg)
        except InputError as exc:
            raise SystemExit(f"scale_probe: {p}: {exc}") from None
        if r is None:
            print(f"scale_probe: {p}: no truth inside the frame, left out", file=sys.stderr)
            continue
        rows.append(r)
        print(
            f"| {Path(p).name} | {r['change']:.2f} | {r['found']:.2f} | {_num(r['followed'])} "
            f"| {r['median_err']:.3f} |",
            flush=True,
        )
    if rows:
        moved = [r for r in rows if abs(math.log(r["change"])) > math.log(1.3)]
        err = np.median([r["median_err"] for r in rows])
        line = f"{len(rows)} sequences: median err {err:.3f}"
        if moved:
            fol = np.nanmedian([r["followed"] for r in moved])
            line += f"; {len(moved)} change size by over 1.3x, median share followed {fol:.2f}"
        print(line)
        return 0
    print("scale_probe: no sequence had truth", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
