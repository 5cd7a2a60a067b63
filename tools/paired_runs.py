"""Two runs of the same scenes compared scene by scene: is a change more than noise?

Usage::

    python tools/paired_runs.py BASE NEW [--metric idf1] [--threshold 0.02] [--worst 3]

``BASE`` and ``NEW`` are ``dualtrack batch`` (or ``dualtrack bench``) output folders, or their
``report.json``, over the same scenes: typically one run with a part switched off
(``--set dual.colour.first_model_excludes_nearer=false``) and one with it on. For each metric
(``--metric``, repeatable; default P@20 and AUC where the scenes have one target, IDF1 and
identity purity on the frames where each target is at least 25 % visible where they have
several) it prints one Markdown row: the scenes both runs scored, the two means, their paired
difference with its standard error (the standard deviation of the per-scene differences over
the square root of their count), the 10th percentile and the worst scene of each run, how many
scenes moved up and down by more than ``--threshold``, and the scenes that lost most.

A mean difference within about two standard errors is within the noise of the scenes drawn;
even a larger one may be the spread of a few fragile scenes (``tools/rounding_spread.py`` shows
how far one scene moves when only the rounding changes).
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DEFAULT_SINGLE = ("p20", "auc")
DEFAULT_MULTI = ("idf1", "purity_visible")


@dataclass(frozen=True)
class Paired:
    """One metric over the scenes two runs share."""

    metric: str
    scenes: int
    base_mean: float
    new_mean: float
    diff: float
    stderr: float
    base_p10: float
    new_p10: float
    base_worst: float
    new_worst: float
    up: int
    down: int
    losers: tuple[tuple[str, float], ...]


def load(path: Path) -> dict[str, dict]:
    """Scene name -> metrics of a run folder's (or a file's) ``report.json``; scenes that failed
    or were not scored are left out."""
    f = path / "report.json" if path.is_dir() else path
    if not f.is_file():
        raise SystemExit(f"paired_runs: no report.json at {path}")
    seqs = json.loads(f.read_text()).get("sequences", {})
    return {k: v["metrics"] for k, v in seqs.items() if v.get("metrics")}


def paired(
    base: dict[str, dict],
    new: dict[str, dict],
    metric: str,
    threshold: float = 0.02,
    worst: int = 3,
) -> Paired | None:
    """The paired comparison of ``metric`` over the scenes both runs scored with a number (None
    where fewer than two have one).

    Examples
    --------
    >>> base = {"a": {"idf1": 0.5}, "b": {"idf1": 0.8}, "c": {"idf1": 0.9}}
    >>> new = {"a": {"idf1": 0.7}, "b": {"idf1": 0.8}, "c": {"idf1": 0.85}}
    >>> p = paired(base, new, "idf1")
    >>> p.scenes, round(p.diff, 4), round(p.stderr, 4), p.up, p.down, p.losers
    (3, 0.05, 0.0764, 1, 1, (('c', -0.05),))
    >>> paired(base, new, "p20") is None
    True
    """
    names = sorted(
        k
        for k in base.keys() & new.keys()
        if _number(base[k].get(metric)) and _number(new[k].get(metric))
    )
    if len(names) < 2:
        return None
    x = np.array([base[k][metric] for k in names], float)
    y = np.array([new[k][metric] for k in names], float)
    d = y - x
    order = np.argsort(d, kind="stable")
    losers = tuple((names[i], round(float(d[i]), 4)) for i in order[:worst] if d[i] < -threshold)
    return Paired(
        metric,
        len(names),
        float(x.mean()),
        float(y.mean()),
        float(d.mean()),
        float(d.std(ddof=1) / math.sqrt(len(d))),
        float(np.percentile(x, 10)),
        float(np.percentile(y, 10)),
        float(x.min()),
        float(y.min()),
        int((d > threshold).sum()),
        int((d < -threshold).sum()),
        losers,
    )


def _number(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def default_metrics(runs: dict[str, dict]) -> tuple[str, ...]:
    """P@20 and AUC for one-target scenes, IDF1 and visible-frame purity where any scene has
    several targets (an ``idf1_visible`` or ``purity_visible`` figure).

    Examples
    --------
    >>> default_metrics({"a": {"p20": 1.0, "auc": 0.8}})
    ('p20', 'auc')
    >>> default_metrics({"a": {"p20": 1.0, "idf1": 0.9, "purity_visible": 0.95}})
    ('idf1', 'purity_visible')
    """
    multi = any(_number(m.get("purity_visible")) for m in runs.values())
    return DEFAULT_MULTI if multi else DEFAULT_SINGLE


def row(p: Paired) -> str:
    """One Markdown table row of ``p``."""
    lost = ", ".join(f"{k} {v:+.3f}" for k, v in p.losers) or "-"
    return (
        f"| {p.metric} | {p.scenes} | {p.base_mean:.4f} -> {p.new_mean:.4f} | "
        f"{p.diff:+.4f} +- {p.stderr:.4f} | {p.base_p10:.3f} -> {p.new_p10:.3f} | "
        f"{p.base_worst:.3f} -> {p.new_worst:.3f} | {p.up} / {p.down} | {lost} |"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("base", type=Path, help="the run to compare against (folder or report.json)")
    ap.add_argument("new", type=Path, help="the run compared (folder or report.json)")
    ap.add_argument("--metric", action="append", default=None, help="a metric key (repeatable)")
    ap.add_argument("--threshold", type=float, default=0.02, help="a scene moved by more")
    ap.add_argument("--worst", type=int, default=3, help="losing scenes listed per metric")
    args = ap.parse_args(argv)
    base, new = load(args.base), load(args.new)
    metrics = tuple(args.metric) if args.metric else default_metrics(base)
    print(
        f"| metric | scenes | mean | paired difference | 10th percentile | worst | "
        f"up / down by > {args.threshold} | lost most |"
    )
    print("|---|---|---|---|---|---|---|---|")
    found = False
    for m in metrics:
        p = paired(base, new, m, args.threshold, args.worst)
        if p is None:
            print(f"| {m} | fewer than 2 scenes scored in both runs | | | | | | |")
            continue
        found = True
        print(row(p))
    return 0 if found else 1


if __name__ == "__main__":
    raise SystemExit(main())
