"""Benchmark-level scores from per-sequence results, in each benchmark's own terms.

* ``default``, ``rgbt234``, ``vtuav`` and ``lasher``: the mean over sequences of each sequence's
  score (RGBT234 and LasHeR average sequences);
* ``gtot``: frames pooled over the whole benchmark (the GTOT toolkit's rule): the per-
  threshold hit counts of every sequence are summed, then turned into MPR@5 and MSR.

Curves for the precision and success plots follow the same rule (mean of per-sequence
curves, or frame-weighted for ``gtot``). Many-target scores (MOTA, IDF1, HOTA, purity)
are means over the sequences that have them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pipeline.eval import Assessment, protocols
from pipeline.io.results import read_tracks
from pipeline.io.sequence import open_sequence

SCORE_KEYS = {
    "default": ("p5", "p20", "auc", "mpr", "msr", "npr"),
    "rgbt234": ("mpr", "msr"),
    "vtuav": ("mpr", "msr"),
    "gtot": ("mpr", "msr"),
    "lasher": ("pr", "npr", "sr"),
}
MULTI_KEYS = ("mota", "idf1", "hota", "id_switches", "idf1_visible", "purity_visible")


def sequence_curves(
    seq_dir: Path, tracks_csv: Path, protocol: str, id_rule: str = "auto"
) -> dict[str, object]:
    """Mean precision (51) and success (21) curves over the targets of one run, its frame
    count with truth, and for ``gtot`` the hit counts to pool (``id_rule`` as in
    :func:`pipeline.eval.evaluate`), read from the run's one :class:`~pipeline.eval.Assessment`."""
    seq = open_sequence(seq_dir)
    a = Assessment(seq.truth, read_tracks(tracks_csv, seq.n_frames), seq.n_frames, id_rule)
    per = a.curves()
    prec = np.mean([c["precision"] for c in per.values()], axis=0)
    succ = np.mean([c["success"] for c in per.values()], axis=0)
    frames = int(sum(int((~np.isnan(c["errors"])).sum()) for c in per.values()))
    out: dict[str, object] = {
        "precision": prec.tolist(),
        "success": succ.tolist(),
        "frames": frames,
    }
    if protocol == "gtot":
        counts = a.gtot_counts()
        out["gtot_counts"] = {
            k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in counts.items()
        }
    return out


def _mean(values: list[object]) -> float | None:
    v = [
        float(x)
        for x in values
        if isinstance(x, int | float) and not (isinstance(x, float) and math.isnan(x))
    ]
    return float(np.mean(v)) if v else None


def aggregate(entries: list[dict[str, object]], protocol: str) -> dict[str, object]:
    """Overall scores of one tracker over ``entries`` (each: ``metrics``, ``curves``,
    ``fps_tracking``, ``frames``) of its finished sequences."""
    out: dict[str, object] = {"sequences": len(entries)}
    if not entries:
        return out
    metrics = [e.get("metrics") or {} for e in entries]
    if protocol == "gtot":
        frames = 0
        pc = np.zeros(51)
        sc = np.zeros(51)
        for e in entries:
            c = (e.get("curves") or {}).get("gtot_counts")  # type: ignore[union-attr]
            if c:
                frames += int(c["frames"])
                pc += np.asarray(c["precision_counts"], float)
                sc += np.asarray(c["success_counts"], float)
        out.update(
            {
                k: v
                for k, v in protocols.gtot_from_counts(frames, pc.tolist(), sc.tolist()).items()
                if k != "frames"
            }
        )
        out["pooled_frames"] = frames
    else:
        for k in SCORE_KEYS[protocol]:
            v = _mean([m.get(k) for m in metrics])  # type: ignore[union-attr]
            if v is not None:
                out[k] = v
    for k in MULTI_KEYS:
        vals = [m.get(k) for m in metrics if k in m]  # type: ignore[operator, union-attr]
        if vals:
            out[k] = int(np.sum(vals)) if k == "id_switches" else _mean(vals)
    # type: ignore[index, union-attr]
    pur = [m["purity"]["overall"] for m in metrics if isinstance(m.get("purity"), dict)]
    if pur:
        out["purity"] = _mean(pur)
    curves = [e["curves"] for e in entries if e.get("curves")]
    if curves:
        if protocol == "gtot":
            w = np.array([max(int(c["frames"]), 0) for c in curves], float)  # type: ignore[index]
            w = w / w.sum() if w.sum() > 0 else np.full(len(curves), 1 / len(curves))
        else:
            w = np.full(len(curves), 1 / len(curves))
        out["precision_curve"] = np.sum(
            [wi * np.asarray(c["precision"]) for wi, c in zip(w, curves, strict=True)], axis=0
        ).tolist()
        out["success_curve"] = np.sum(
            [wi * np.asarray(c["success"]) for wi, c in zip(w, curves, strict=True)], axis=0
        ).tolist()
    fps = [e.get("fps_tracking") for e in entries]
    out["fps_tracking_mean"] = _mean(fps)
    frames_all = [int(e.get("frames") or 0) for e in entries]  # type: ignore[call-overload]
    secs = sum(
        f / float(p)
        for f, p in zip(frames_all, fps, strict=True)
        if isinstance(p, int | float) and p > 0
    )
    out["frames"] = int(sum(frames_all))
    out["fps_tracking_pooled"] = float(sum(frames_all) / secs) if secs > 0 else None
    return out
