"""Scores restricted to the frames that carry a challenge attribute (random scenes'
``frame_attributes``).

A random scene's ``scene.json`` flags, per target and frame, occlusion, shadow, darkness,
clutter, crossover, out of view, scale change and fast motion (1-based inclusive frame
ranges). :func:`attribute_counts` counts, for one run, the frames with truth that carry
each attribute and how many of them the tracker got right (centre error <= 20 px; IoU
above each success threshold), against the scored channel's truth as the default
protocol does; :func:`pool_counts` adds the counts of many runs and turns them into
P@20 and AUC per attribute (frames pooled, so a long episode weighs by its length).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pipeline.eval.single import SUCCESS_THRESHOLDS

if TYPE_CHECKING:
    from pipeline.eval import Assessment


def attribute_masks(meta: dict[str, object], n_frames: int) -> dict[int, dict[str, np.ndarray]]:
    """``{target id: {attribute: (n_frames,) bool}}`` from a scene's ``frame_attributes`` (empty if
    none)."""
    fa = meta.get("frame_attributes")
    out: dict[int, dict[str, np.ndarray]] = {}
    if not isinstance(fa, dict):
        return out
    for tid, attrs in fa.items():
        if not isinstance(attrs, dict):
            continue
        masks = {}
        for name, ranges in attrs.items():
            m = np.zeros(n_frames, bool)
            for a, b in ranges if isinstance(ranges, list) else []:
                m[max(int(a), 1) - 1 : min(int(b), n_frames)] = True
            masks[str(name)] = m
        out[int(tid)] = masks
    return out


def attribute_counts(
    assessment: Assessment, masks: dict[int, dict[str, np.ndarray]]
) -> dict[str, dict[str, object]]:
    """Per attribute: frames with truth carrying it, hits at 20 px, hits per success threshold,
    read from the run's :class:`~pipeline.eval.Assessment` (its errors and IoUs per truth id)."""
    out: dict[str, dict[str, object]] = {}
    for g in assessment.ids:
        err, ov = assessment.errors[g], assessment.overlaps[g]
        has = ~np.isnan(err)
        for name, m in masks.get(g, {}).items():
            sel = m[: err.shape[0]] & has
            c = out.setdefault(
                name,
                {
                    "frames": 0,
                    "p20_hits": 0,
                    "success_hits": np.zeros(SUCCESS_THRESHOLDS.size, int),
                },
            )
            c["frames"] = int(c["frames"]) + int(sel.sum())
            c["p20_hits"] = int(c["p20_hits"]) + int((err[sel] <= 20.0).sum())
            hits = (ov[sel][None, :] > SUCCESS_THRESHOLDS[:, None]).sum(axis=1)
            c["success_hits"] = np.asarray(c["success_hits"]) + hits
    return out


def pool_counts(counts: list[dict[str, dict[str, object]]]) -> dict[str, dict[str, float]]:
    """Sum the counts of many runs; ``{attribute: {"frames", "p20", "auc"}}`` (NaN scores without
    frames)."""
    total: dict[str, dict[str, object]] = {}
    for c in counts:
        for name, v in c.items():
            t = total.setdefault(
                name,
                {
                    "frames": 0,
                    "p20_hits": 0,
                    "success_hits": np.zeros(SUCCESS_THRESHOLDS.size, int),
                },
            )
            t["frames"] = int(t["frames"]) + int(v["frames"])  # type: ignore[call-overload]
            t["p20_hits"] = int(t["p20_hits"]) + int(v["p20_hits"])  # type: ignore[call-overload]
            # type: ignore[operator]
            t["success_hits"] = t["success_hits"] + np.asarray(v["success_hits"])
    out = {}
    for name, t in total.items():
        n = int(t["frames"])  # type: ignore[call-overload]
        out[name] = {
            "frames": float(n),
            "p20": float(t["p20_hits"]) / n if n else float("nan"),  # type: ignore[arg-type]
            "auc": float(np.mean(np.asarray(t["success_hits"]) / n)) if n else float("nan"),
        }
    return out
