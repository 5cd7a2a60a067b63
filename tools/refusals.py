"""Whether the dual tracker's coasts were right to refuse the filter: where its detection was.

On a coasting frame (a decision ``coast:<rule>``: partial evidence, a filter on the background,
a measurement another target took) the correlation filter has usually still found something;
the decider refused it (not confident, out of reach, on the still background, vetoed by the
colour). This tool runs the dual tracker in memory (:func:`pipeline.run.track`) on every
sequence folder with ground truth under ROOT and, for each such target-frame with truth, puts
the filter's detection (the ``appearance`` overlay of the result) in a class by its centre's
distance to the truth's:

``on``
    within 5 px: the refusal lost a measurement of the target;
``near``
    within 20 px (the P@20 radius);
``off``
    farther: the refusal was right.

Printed by coast rule, and for every coast by the filter's PSR band, as counts and the share
``on``. A refusal rule whose refused detections are mostly ``on`` refuses the target; one whose
detections are mostly ``off`` earns its place.

A second table asks whether anything looked where the target was, on the coasting and the lost
target-frames of a target in view (visibility at least 0.25, where the sequence's ``scene.json``
gives it; every frame with truth otherwise), each in the first class that holds (:func:`reach`):

``filter``
    the filter's detection within 20 px of the truth's centre: a cue saw the target and the
    decision refused it (thresholds can win these back);
``prediction``
    the reported box (the prediction the target coasts on, or where a lost one was last
    believed) within 20 px: the search started at the target and found nothing there;
``neither``
    the search was elsewhere: the prediction had left the target, and only a search that
    reaches farther can find it again.

Usage::

    python tools/refusals.py runs/dev/scenes --jobs 2
    python tools/refusals.py runs/dev/scenes --set dual.decider.background_share=0

``ROOT`` holds sequence folders (``dualtrack synth random --seeds 0-119 --out ROOT``);
development seeds are 0-999 (test seeds 1000-1999 are scored once, when an issue closes).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from pipeline.eval import MIN_VISIBILITY  # the share of a target in view (0.25)

CLASSES = ("on", "near", "off")
NEAR_PX = 20.0  # the P@20 radius: "near" the truth
PSR_BANDS = (0.0, 7.0, 9.0, 12.0, 20.0)  # band edges; 7 and 9 are the decider's defaults


def distance_class(distance_px: float) -> str:
    """The class of a refused detection by its centre's distance to the truth's, px.

    Examples
    --------
    >>> [distance_class(d) for d in (0.0, 5.0, 5.1, 20.0, 21.0)]
    ['on', 'on', 'near', 'near', 'off']
    """
    if distance_px <= 5.0:
        return "on"
    return "near" if distance_px <= NEAR_PX else "off"


def psr_band(psr: float) -> str:
    """The PSR band of a detection (``nan`` where the filter gave none).

    Examples
    --------
    >>> [psr_band(p) for p in (3.0, 7.0, 10.5, 25.0, float("nan"))]
    ['0-7', '7-9', '9-12', '>=20', 'nan']
    """
    if math.isnan(psr):
        return "nan"
    for lo, hi in itertools.pairwise(PSR_BANDS):
        if lo <= psr < hi:
            return f"{lo:g}-{hi:g}"
    return f">={PSR_BANDS[-1]:g}"


def _with_truth(frames, truth: dict[int, np.ndarray], cases: tuple[str, ...], visibility=None):
    """``(result, truth centre)`` of every target-frame of ``frames`` whose decision's case is
    one of ``cases`` and that has truth (``truth[id]``: ``(N, 4)`` boxes, NaN rows none); with
    ``visibility[id]`` (``(N,)``), only where the target is at least ``MIN_VISIBILITY`` visible
    (a missing id: every frame)."""
    for fr in frames:
        k = fr.frame - 1
        for r in fr.targets:
            boxes = truth.get(r.id)
            if r.decision is None or str(r.decision.case) not in cases or boxes is None:
                continue
            if k >= len(boxes) or np.isnan(boxes[k]).any():
                continue
            vis = (visibility or {}).get(r.id)
            if vis is not None and k < len(vis) and vis[k] < MIN_VISIBILITY:
                continue
            x, y, w, h = boxes[k]
            yield r, (x + w / 2, y + h / 2)


def _distance(box, centre: tuple[float, float]) -> float:
    """Distance of ``box``'s centre to ``centre``, px (inf without a box)."""
    return math.inf if box is None else math.hypot(box.cx - centre[0], box.cy - centre[1])


def tally(frames, truth: dict[int, np.ndarray]) -> Counter:
    """``(key, class)`` counts of one run: ``frames`` its :class:`~pipeline.types.FrameResult`
    list, ``truth[id]`` the ``(N, 4)`` truth boxes (NaN rows: none). Keys are ``rule:<coast
    rule>`` and ``psr:<band>``."""
    out: Counter = Counter()
    for r, centre in _with_truth(frames, truth, ("coast",)):
        app = r.overlays.get("appearance")
        if app is None:
            continue
        cls = distance_class(_distance(app, centre))
        rule = r.decision.rule.value.split("{", 1)[0].rstrip("-")  # the rule, without its details
        out[(f"rule:{rule}", cls)] += 1
        out[(f"psr:{psr_band(float(r.diagnostics.get('psr', math.nan)))}", cls)] += 1
    return out


REACH = ("filter", "prediction", "neither")


def reach(
    frames, truth: dict[int, np.ndarray], visibility: dict[int, np.ndarray] | None = None
) -> Counter:
    """``(case, class)`` counts of one run's coasting and lost target-frames in view: ``case``
    ``coast`` or ``lost``, ``class`` one of :data:`REACH` (see the module's doc). ``frames`` is
    its :class:`~pipeline.types.FrameResult` list, ``truth[id]`` the ``(N, 4)`` truth boxes (NaN
    rows: none), ``visibility[id]`` the ``(N,)`` visible share of each target (frames under
    ``MIN_VISIBILITY`` are left out; None or a missing id: every frame counts)."""
    out: Counter = Counter()
    for r, centre in _with_truth(frames, truth, ("coast", "lost"), visibility):
        cls = _reach_class(r.overlays.get("appearance"), r.box, centre)
        out[(str(r.decision.case), cls)] += 1
    return out


def _reach_class(found, box, centre: tuple[float, float]) -> str:
    """The :data:`REACH` class of a frame: the filter's box ``found`` and the reported ``box``
    (either may be None) against the truth's ``centre``.

    Examples
    --------
    >>> from pipeline.types import BBox
    >>> at = lambda cx: BBox.from_center(cx, 50, 10, 20)
    >>> [_reach_class(f, b, (100, 50)) for f, b in ((at(110), at(150)), (at(150), at(85)),
    ...                                           (None, at(150)), (at(150), None))]
    ['filter', 'prediction', 'neither', 'neither']
    """
    if _distance(found, centre) <= NEAR_PX:
        return "filter"
    return "prediction" if _distance(box, centre) <= NEAR_PX else "neither"


def reach_table(counts: Counter) -> list[str]:
    """The markdown table of ``counts`` (:func:`reach`): frames and shares of each class."""
    lines = [
        "| case | frames | filter on the target | prediction at it | neither |",
        "|---|---|---|---|---|",
    ]
    for case in ("coast", "lost"):
        n = [counts[(case, c)] for c in REACH]
        total = sum(n)
        if total:
            cells = " | ".join(f"{v} ({v / total:.0%})" for v in n)
            lines.append(f"| {case} | {total} | {cells} |")
    return lines


def _visibility(meta: dict) -> dict[int, np.ndarray] | None:
    """Each target's visible share from a synthetic scene's ``scene.json`` (None without it)."""
    vis = meta.get("visibility")
    if not isinstance(vis, dict):
        return None
    return {int(k): np.asarray(v, float) for k, v in vis.items()}


def _one(args: tuple[str, tuple[str, ...]]) -> tuple[Counter, Counter]:
    path, sets = args
    from pipeline.config import PipelineConfig, apply_overrides, parse_set
    from pipeline.io.sequence import open_sequence
    from pipeline.run import track

    cfg = apply_overrides(PipelineConfig(), parse_set(list(sets))) if sets else None
    seq = open_sequence(path)
    truth = seq.truth.primary()
    if not truth:
        return Counter(), Counter()
    frames = list(track(seq, "dual", config=cfg))
    return tally(frames, truth), reach(frames, truth, _visibility(seq.meta))


def table(counts: Counter) -> list[str]:
    """The markdown table of ``counts`` (:func:`tally`), rules by frames, then the PSR bands."""
    keys = {k for k, _ in counts}
    rules = sorted(
        (k for k in keys if k.startswith("rule:")),
        key=lambda k: -sum(counts[(k, c)] for c in CLASSES),
    )
    bands = [psr_band(p) for p in PSR_BANDS] + ["nan"]
    lines = ["| coast | frames | on | near | off | share on |", "|---|---|---|---|---|---|"]
    for k in rules + [f"psr:{b}" for b in bands if f"psr:{b}" in keys]:
        n = [counts[(k, c)] for c in CLASSES]
        total = sum(n)
        share = f"{n[0] / total:.2f}" if total else ""
        lines.append(f"| {k} | {total} | {n[0]} | {n[1]} | {n[2]} | {share} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("root", type=Path, help="a folder of sequence folders with ground truth")
    p.add_argument("--jobs", type=int, default=1, help="sequences run at once (default 1)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    a = p.parse_args(argv)
    if not a.root.is_dir():
        print(f"refusals: {a.root} is not a folder", file=sys.stderr)
        return 2
    from pipeline.io.sequence import sequence_layout

    seqs = sorted(str(d) for d in a.root.iterdir() if sequence_layout(d) is not None)
    if not seqs:
        print(f"refusals: no sequence folder in {a.root}", file=sys.stderr)
        return 2
    total: Counter = Counter()
    reached: Counter = Counter()
    jobs = [(s, tuple(a.set)) for s in seqs]
    if a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            results = list(ex.map(_one, jobs))
    else:
        results = [_one(j) for j in jobs]
    for c, r in results:
        total.update(c)
        reached.update(r)
    print(f"{len(seqs)} sequences; the filter's detection on coasting target-frames:\n")
    print("\n".join(table(total)))
    print("\nWhere the search was on the coasting and lost target-frames in view:\n")
    print("\n".join(reach_table(reached)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
