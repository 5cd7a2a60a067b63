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
detections are mostly ``off`` earns its place. Usage::

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

CLASSES = ("on", "near", "off")
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
    return "near" if distance_px <= 20.0 else "off"


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


def tally(frames, truth: dict[int, np.ndarray]) -> Counter:
    """``(key, class)`` counts of one run: ``frames`` its :class:`~pipeline.types.FrameResult`
    list, ``truth[id]`` the ``(N, 4)`` truth boxes (NaN rows: none). Keys are ``rule:<coast
    rule>`` and ``psr:<band>``."""
    out: Counter = Counter()
    for fr in frames:
        for r in fr.targets:
            d = r.decision
            app = r.overlays.get("appearance")
            boxes = truth.get(r.id)
            if d is None or str(d.case) != "coast" or app is None or boxes is None:
                continue
            if fr.frame > len(boxes) or np.isnan(boxes[fr.frame - 1]).any():
                continue
            x, y, w, h = boxes[fr.frame - 1]
            cls = distance_class(math.hypot(app.cx - (x + w / 2), app.cy - (y + h / 2)))
            rule = d.rule.value.split("{", 1)[0].rstrip("-")  # the rule, without its details
            out[(f"rule:{rule}", cls)] += 1
            out[(f"psr:{psr_band(float(r.diagnostics.get('psr', math.nan)))}", cls)] += 1
    return out


def _one(args: tuple[str, tuple[str, ...]]) -> Counter:
    path, sets = args
    from pipeline.config import PipelineConfig, apply_overrides, parse_set
    from pipeline.io.sequence import open_sequence
    from pipeline.run import track

    cfg = apply_overrides(PipelineConfig(), parse_set(list(sets))) if sets else None
    seq = open_sequence(path)
    truth = seq.truth.primary()
    if not truth:
        return Counter()
    return tally(track(seq, "dual", config=cfg), truth)


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
    jobs = [(s, tuple(a.set)) for s in seqs]
    if a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            for c in ex.map(_one, jobs):
                total.update(c)
    else:
        for j in jobs:
            total.update(_one(j))
    print(f"{len(seqs)} sequences; the filter's detection on coasting target-frames:\n")
    print("\n".join(table(total)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
