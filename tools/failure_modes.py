"""Where a tracker misses the truth on random scenes, and why: its failed target-frames by cause.

Usage: python tools/failure_modes.py RUN_ROOT [--tracker dual] [--worst 10] [--onsets N]
       [--by-target] [--by-rule]

``RUN_ROOT`` is a ``dualtrack bench --random N --out RUN_ROOT`` folder (``scenes/`` and
``runs/<tracker>/<scene>/targets.csv``), or any folder laid out so: ``scenes/`` may be a set
written by ``dualtrack synth random --seeds A-B`` and ``runs/<tracker>/`` a ``dualtrack batch``
run over it. Every scene is drawn again from its seed and rendered once more (its
``scene.json`` names the seed and the generator options), which gives the boxes of the moving
objects that are not targets, and each frame of each target whose output box has IoU < 0.5
with the truth is put in the first class that applies:

``hidden``
    the target's visibility (share of its own pixels nothing covers) is under 0.25: no tracker
    sees it, a coast is all there is;
``on-other``
    the output box overlaps another target or a distractor (IoU >= 0.3) more than the target:
    an identity taken over;
``lost``
    no output box (status ``lost``) while the target is in view;
``coasting``
    an occluded status (the tracker knows it has no measurement) while the target is in view
    (split below the table by whether the truth's centre lies inside the filter's search window
    around the coasting box, ``1 + padding`` = 2.5 times its size: the target is where the
    filter looks and is not recognised, or the prediction has left it; and by the decision's rule:
    a coast's, or that of a measurement reported occluded, such as a collapsed contour's);
``size``
    the centre is within 20 px of the truth's, but the box's size is wrong (split below the
    table by whether the box is smaller or larger than the truth's, and by the target's depth
    motion: ``approach``, ``recede`` or ``constant``, from ``scene.json``);
``drift``
    anything else: the tracker measures the target somewhere it is not.

Prints one table row per scene (the worst ``--worst`` first) and the totals, as shares of all
target-frames with truth.

``--onsets N`` also lists the N targets that fail longest, each at the onset of its first
sustained failure (``--run`` consecutive failed frames, default 10, the target at least 0.25
visible on each): the frame, the class there, the tracker's decision on the frame before and at
the onset, and the target's visibility on frame 1 (a first box partly hidden, or holding another
object, is where a filter can learn the wrong thing). Failures that begin at a track's start read
differently from drifts late in a crossing; this is where to look before changing a rule.

``--by-target`` also tabulates the failures by the kind of target (from ``scene.json``: its
``kind``, ``motion``, depth motion, whether it enters through the border) and by its first frame
(its box overlapping another target's by at least a tenth of the smaller box, the nearer of the
two being the one whose box reaches lower in the frame; visibility under 0.9): per group the
targets, their target-frames in view (visibility >= 0.25), the share of those failed and the
group's share of all failed target-frames in view. ``--by-rule`` tabulates the same frames by the
decision the tracker made on them (``targets.csv``'s ``decision``, its numbers and other targets'
ids dropped): how often each rule's measurement, or coast, misses the target.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.synthetic.family import draw_scene
from pipeline.synthetic.scene import Renderer

CLASSES = ("hidden", "on-other", "lost", "coasting", "size", "drift")
Box = tuple[float, float, float, float]


def intersection(a: Box, b: Box) -> float:
    """The area two boxes share, px^2."""
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    return ix * iy


def iou(a: Box, b: Box) -> float:
    inter = intersection(a, b)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def centre_distance(a: Box, b: Box) -> float:
    return float(np.hypot(a[0] + a[2] / 2 - b[0] - b[2] / 2, a[1] + a[3] / 2 - b[1] - b[3] / 2))


@dataclass(frozen=True)
class Onset:
    """A target's first sustained failure in one run (see ``--onsets``)."""

    scene: str
    target: int
    frame: int
    cls: str
    before: str  # the decision on the frame before the onset
    at: str  # the decision at the onset
    first_visibility: float
    failed: int  # the target's failed target-frames in the run, sustained or not


@dataclass(frozen=True)
class SceneFailures:
    """One run's failures on one scene (see :func:`scene_failures`)."""

    counts: Counter  # failed target-frames per class (and the size and coasting splits)
    total: int  # target-frames with truth
    onsets: list[Onset]
    groups: Counter  # (group, "targets" | "frames" | "failed") -> count, for --by-target
    rules: Counter  # (rule, "frames" | "failed") -> count, for --by-rule


def scene_failures(scene_dir: Path, run_dir: Path, run: int = 10) -> SceneFailures:
    """The failures of one run: the failed target-frames per class, the target-frames with
    truth, each target's first sustained failure (``run`` consecutive failed frames with the
    target at least 0.25 visible), and the frames in view tallied by target group and by
    decision rule."""
    meta = json.loads((scene_dir / "scene.json").read_text())
    gen = meta.get("generator")
    if gen is None:
        raise SystemExit(
            f"{scene_dir}/scene.json names no generator options: write the scene again "
            "(dualtrack synth random or dualtrack bench --random) to classify its failures"
        )
    t = gen.get("targets")
    targets = tuple(t) if isinstance(t, list) else t
    size = tuple(gen.get("size") or (meta["width"], meta["height"]))
    frames = int(gen.get("frames") or meta["frames"])
    drawn = draw_scene(int(meta["seed"]), targets, int(size[0]), int(size[1]), frames)
    renderer = Renderer(drawn.scene, drawn.render_seed)
    out: dict[tuple[int, int], tuple[str, tuple[float, float, float, float], str]] = {}
    with open(run_dir / "targets.csv") as fh:
        for r in csv.DictReader(fh):
            box = tuple(float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))
            out[(int(r["frame"]), int(r["id"]))] = (r["status"], box, r.get("decision", ""))
    params = {int(p["id"]): p for p in meta.get("params", {}).get("targets", [])}
    depth = {tid: str(p.get("scale", "constant")) for tid, p in params.items()}
    groups: Counter = Counter()
    rules: Counter = Counter()
    in_view: dict[int, list[bool]] = {}  # per target: failed, on each frame in view
    counts: Counter = Counter()
    total = 0
    # per target: (frame, class or None when on the target or hidden, decision)
    seq: dict[int, list[tuple[int, str | None, str]]] = {}
    first_vis: dict[int, float] = {}
    first_boxes: dict[int, Box] = {}
    for t in range(1, drawn.scene.n_frames + 1):
        f = renderer.render_frame(t)
        others = [b for b in (f.others or {}).values() if b is not None]
        for tid, truth in f.truth_visible.items():
            if t == 1:
                first_vis[tid] = float(f.visibility.get(tid, 0.0))
                if truth is not None:
                    first_boxes[tid] = truth
            if truth is None:
                continue
            total += 1
            status, box, decision = out.get((t, tid), ("lost", (0.0, 0.0, 0.0, 0.0), ""))
            cls = _failure(status, box, truth, f, tid, others)
            if cls is not None:
                counts[cls] += 1
            if cls == "size":
                counts[size_key(box, truth, depth.get(tid, "constant"))] += 1
            if cls == "coasting":
                counts[coast_key(box, truth, decision)] += 1
            seq.setdefault(tid, []).append((t, None if cls == "hidden" else cls, decision))
            if cls != "hidden":
                in_view.setdefault(tid, []).append(cls is not None)
                key = rule_key(decision)
                rules[(key, "frames")] += 1
                rules[(key, "failed")] += cls is not None
    for tid, failed in in_view.items():
        for g in target_groups(params.get(tid, {}), tid, first_boxes, first_vis.get(tid, 1.0)):
            groups[(g, "targets")] += 1
            groups[(g, "frames")] += len(failed)
            groups[(g, "failed")] += sum(failed)
    return SceneFailures(
        counts, total, _onsets(scene_dir.name, seq, first_vis, run), groups, rules
    )


def _failure(status, box, truth, f, tid, others) -> str | None:
    """The class of a target-frame (None: on the target, IoU >= 0.5)."""
    shown = status != "lost"
    if shown and iou(box, truth) >= 0.5:
        return None
    rivals = [b for j, b in f.truth_visible.items() if j != tid and b is not None] + others
    if f.visibility.get(tid, 0.0) < 0.25:
        return "hidden"
    if shown and any(iou(box, b) >= 0.3 and iou(box, b) > iou(box, truth) for b in rivals):
        return "on-other"
    if not shown:
        return "lost"
    if status.startswith("occluded"):
        return "coasting"
    if centre_distance(box, truth) <= 20:
        return "size"
    return "drift"


def size_key(box: Box, truth: Box, depth: str) -> str:
    """The key a ``size`` failure is counted under: ``size:<small|large>:<depth>``, by the
    output box's area against the truth's and the target's depth motion.

    Examples
    --------
    >>> size_key((0, 0, 10, 20), (0, 0, 15, 30), "approach")
    'size:small:approach'
    """
    return f"size:{'small' if box[2] * box[3] < truth[2] * truth[3] else 'large'}:{depth}"


def size_split(counts: Counter) -> str:
    """One line saying how the ``size`` failures of ``counts`` split: the share with a box
    smaller than the truth's and, of those, the share on approaching targets; the share with a
    larger box and, of those, on receding targets.

    Examples
    --------
    >>> c = Counter({"size": 4, "size:small:approach": 2, "size:small:constant": 1,
    ...              "size:large:recede": 1})
    >>> size_split(c)
    'size failures (4): box too small 75 % (2 of 3 on approaching targets), too large 25 % (1 of 1 on receding targets)'
    """  # noqa: E501
    n = counts["size"]
    if n == 0:
        return "size failures: none"
    small = sum(v for k, v in counts.items() if k.startswith("size:small:"))
    large = sum(v for k, v in counts.items() if k.startswith("size:large:"))
    return (
        f"size failures ({n}): box too small {100 * small / n:.0f} % "
        f"({counts['size:small:approach']} of {small} on approaching targets), too large "
        f"{100 * large / n:.0f} % ({counts['size:large:recede']} of {large} on receding targets)"
    )


def coast_key(box: Box, truth: Box, decision: str, window: float = 2.5) -> str:
    """The key a ``coasting`` failure is counted under: ``coasting:<in|off>:<rule>``, by whether
    the truth's centre lies inside the search window (``window`` times the box per axis: the
    filter's ``1 + padding``) centred on the coasting box, and the decision's rule (its part after
    the case: ``coast:partial-evidence``, or ``appearance:appearance-contour-collapse`` for a
    measurement reported occluded).

    Examples
    --------
    >>> coast_key((0, 0, 10, 20), (8, 5, 10, 20), "coast:partial-evidence")
    'coasting:in:partial-evidence'
    >>> coast_key((0, 0, 10, 20), (20, 0, 10, 20), "coast:filter-on-background")
    'coasting:off:filter-on-background'
    """
    dx = abs(box[0] + box[2] / 2 - truth[0] - truth[2] / 2)
    dy = abs(box[1] + box[3] / 2 - truth[1] - truth[3] / 2)
    inside = dx <= window * box[2] / 2 and dy <= window * box[3] / 2
    rule = decision.partition(":")[2] or "unknown"
    return f"coasting:{'in' if inside else 'off'}:{rule}"


def coast_split(counts: Counter) -> str:
    """One line saying how the ``coasting`` failures of ``counts`` split: the share whose truth
    lies inside the filter's window around the coast, and the rules of each part, most
    frequent first.

    Examples
    --------
    >>> c = Counter({"coasting": 4, "coasting:in:partial-evidence": 1,
    ...              "coasting:off:partial-evidence": 2, "coasting:off:filter-on-background": 1})
    >>> print(coast_split(c))
    coasting failures (4): truth inside the filter's window 25 % (partial-evidence 1), outside 75 % (partial-evidence 2, filter-on-background 1)
    """  # noqa: E501
    n = counts["coasting"]
    if n == 0:
        return "coasting failures: none"

    def part(where: str) -> tuple[int, str]:
        head = f"coasting:{where}:"
        rules = Counter({k[len(head) :]: v for k, v in counts.items() if k.startswith(head)})
        return sum(rules.values()), ", ".join(f"{r} {v}" for r, v in rules.most_common())

    (k_in, r_in), (k_off, r_off) = part("in"), part("off")
    return (
        f"coasting failures ({n}): truth inside the filter's window {100 * k_in / n:.0f} % "
        f"({r_in or 'none'}), outside {100 * k_off / n:.0f} % ({r_off or 'none'})"
    )


def rule_key(decision: str) -> str:
    """The decision a target-frame is tallied under by ``--by-rule``: ``targets.csv``'s
    ``decision`` with its numbers and the other targets' ids dropped.

    Examples
    --------
    >>> rule_key("lost:51-frames-without-a-measurement")
    'lost:N-frames-without-a-measurement'
    >>> rule_key("coast:measurement-taken-by-T2")
    'coast:measurement-taken-by-T'
    >>> rule_key("")
    'none'
    """
    return re.sub(r"\d+", "N", re.sub(r"-T\d+$", "-T", decision)) or "none"


def target_groups(
    params: dict, tid: int, first_boxes: dict[int, Box], first_visibility: float
) -> list[str]:
    """The ``--by-target`` groups of target ``tid``: ``all``, its ``kind``, ``motion``,
    ``depth`` (``scale``) and ``entering`` from its ``scene.json`` parameters, and its first
    frame: ``start=behind another target`` / ``start=in front of another target`` where its
    truth box overlaps another's by at least a tenth of the smaller box (the nearer is the one
    reaching lower in the frame), else ``start=clear``; ``start=partly hidden`` where under 0.9
    of it is visible.

    Examples
    --------
    >>> boxes = {1: (10.0, 10.0, 10.0, 30.0), 2: (15.0, 20.0, 10.0, 30.0), 3: (90.0, 0, 5, 5)}
    >>> target_groups({"kind": "person", "motion": "fast", "scale": "approach",
    ...                "entering": False}, 1, boxes, 0.6)
    ['all', 'kind=person', 'motion=fast', 'depth=approach', 'entering=no', 'start=behind another target', 'start=partly hidden']
    >>> target_groups({}, 2, boxes, 1.0)[-1], target_groups({}, 3, boxes, 1.0)[-1]
    ('start=in front of another target', 'start=clear')
    """  # noqa: E501
    out = ["all"]
    for key, name in (("kind", "kind"), ("motion", "motion"), ("scale", "depth")):
        if key in params:
            out.append(f"{name}={params[key]}")
    if "entering" in params:
        out.append(f"entering={'yes' if params['entering'] else 'no'}")
    mine = first_boxes.get(tid)
    behind = in_front = False
    if mine is not None:
        for other, box in first_boxes.items():
            if other == tid:
                continue
            if intersection(mine, box) < 0.1 * min(mine[2] * mine[3], box[2] * box[3]):
                continue
            if box[1] + box[3] > mine[1] + mine[3]:
                behind = True
            else:
                in_front = True
    if behind:
        out.append("start=behind another target")
    elif in_front:
        out.append("start=in front of another target")
    else:
        out.append("start=clear")
    if first_visibility < 0.9:
        out.append("start=partly hidden")
    return out


def group_table(tally: Counter, what: str, fields: tuple[str, ...]) -> list[str]:
    """Markdown rows of ``tally`` ((key, field) -> count, as :class:`SceneFailures` holds):
    per key its ``fields`` other than ``failed``, the failed share of its frames and its share
    of all failed frames (those of the key ``all`` where there is one, else the sum), most
    failed frames first.

    Examples
    --------
    >>> t = Counter({("a", "frames"): 10, ("a", "failed"): 5, ("b", "frames"): 30,
    ...              ("b", "failed"): 3})
    >>> print("\\n".join(group_table(t, "rule", ("frames", "failed"))))
    | rule | frames | failed | share of failures |
    |---|---|---|---|
    | a | 10 | 0.500 | 0.62 |
    | b | 30 | 0.100 | 0.38 |
    """
    keys = sorted({k for k, _ in tally}, key=lambda k: (-tally[(k, "failed")], k))
    everything = tally[("all", "failed")] or sum(tally[(k, "failed")] for k in keys)
    rows = [f"| {what} | " + " | ".join(fields) + " | share of failures |"]
    rows.append("|---|" + "---|" * (len(fields) + 1))
    for k in keys:
        n, bad = tally[(k, "frames")], tally[(k, "failed")]
        cells = [str(tally[(k, f)]) for f in fields if f != "failed"]
        cells.append(f"{bad / max(n, 1):.3f}")
        rows.append(f"| {k} | " + " | ".join(cells) + f" | {bad / max(everything, 1):.2f} |")
    return rows


def _onsets(
    scene: str,
    seq: dict[int, list[tuple[int, str | None, str]]],
    first_vis: dict[int, float],
    run: int,
) -> list[Onset]:
    """Each target's first run of ``run`` consecutive failed, visible frames."""
    found = []
    for tid, frames in seq.items():
        failed = [c is not None for _, c, _ in frames]
        for i in range(len(frames) - run + 1):
            if all(failed[i : i + run]):
                before = frames[i - 1][2] if i > 0 else ""
                f, cls, at = frames[i]
                assert cls is not None
                found.append(
                    Onset(scene, tid, f, cls, before, at, first_vis.get(tid, 1.0), sum(failed))
                )
                break
    return found


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", type=Path)
    ap.add_argument("--tracker", default="dual")
    ap.add_argument("--worst", type=int, default=10)
    ap.add_argument("--onsets", type=int, default=0, metavar="N")
    ap.add_argument("--run", type=int, default=10, metavar="FRAMES")
    ap.add_argument("--by-target", action="store_true", help="failures by target group")
    ap.add_argument("--by-rule", action="store_true", help="failures by decision rule")
    a = ap.parse_args(argv)
    rows = []
    onsets: list[Onset] = []
    grand: Counter = Counter()
    groups: Counter = Counter()
    rules: Counter = Counter()
    n_all = 0
    for scene_dir in sorted((a.root / "scenes").iterdir()):
        run_dir = a.root / "runs" / a.tracker / scene_dir.name
        if not (run_dir / "targets.csv").is_file():
            continue
        sf = scene_failures(scene_dir, run_dir, a.run)
        c, n = sf.counts, sf.total
        onsets += sf.onsets
        grand.update(c)
        groups.update(sf.groups)
        rules.update(sf.rules)
        n_all += n
        rows.append((sum(c[k] for k in CLASSES) / max(n, 1), scene_dir.name, c, n))
    rows.sort(reverse=True)
    print("| scene | failed | " + " | ".join(CLASSES) + " |")
    print("|---|---|" + "---|" * len(CLASSES))
    for share, name, c, n in rows[: a.worst]:
        print(f"| {name} | {share:.3f} | " + " | ".join(f"{c[k] / n:.3f}" for k in CLASSES) + " |")
    print(
        f"| all ({len(rows)} scenes) | {sum(grand[k] for k in CLASSES) / max(n_all, 1):.3f} | "
        + " | ".join(f"{grand[k] / max(n_all, 1):.3f}" for k in CLASSES)
        + " |"
    )
    print("\n" + size_split(grand))
    print(coast_split(grand))
    if a.onsets > 0:
        _print_onsets(onsets, a.onsets, a.run)
    if a.by_target:
        print("\nTarget-frames in view (visibility >= 0.25) by target group:\n")
        print("\n".join(group_table(groups, "group", ("targets", "frames", "failed"))))
    if a.by_rule:
        print("\nTarget-frames in view by the tracker's decision on them:\n")
        print("\n".join(group_table(rules, "decision", ("frames", "failed"))))
    return 0


def _print_onsets(onsets: list[Onset], n: int, run: int) -> None:
    early = sum(o.frame <= run for o in onsets)
    print(
        f"\n{len(onsets)} targets fail for {run}+ frames in view; {early} of them from within "
        f"the first {run} frames. The {min(n, len(onsets))} that fail longest:\n"
    )
    head = ("scene", "target", "onset", "class", "before", "at", "vis. 1", "failed")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for o in sorted(onsets, key=lambda o: -o.failed)[:n]:
        print(
            f"| {o.scene} | {o.target} | {o.frame} | {o.cls} | {o.before} | {o.at} | "
            f"{o.first_visibility:.2f} | {o.failed} |"
        )


if __name__ == "__main__":
    raise SystemExit(main())
