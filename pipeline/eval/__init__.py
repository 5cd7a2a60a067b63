"""Evaluation against ground truth (``dualtrack evaluate`` and the end of every ``track`` run).

:func:`evaluate` returns the object ``evaluate --json`` prints (docs/formats.md):

* default protocol: top-level ``p5``, ``p20``, ``auc``, ``mean_error_px``, ``npr`` (means
  over targets), scored against the visible truth when both channels have truth, else the
  one truth there is; ``mpr`` and ``msr`` when both channels have truth; with several
  targets also ``mota``, ``motp``, ``idf1``, ``id_switches``, ``purity``, ``hota``;
  ``targets``: ``{"<id>": same per-target keys}``;
* ``protocol="gtot" | "rgbt234" | "lasher" | "vtuav"``: the toolkit's own keys and rules
  (``pipeline.eval.protocols``), per target and averaged.

Which track is scored against which truth id (``id_rule``): ``truth`` - the track carrying the
truth's id (trackers initialised from the truth or by ``--init``: a tracker that swaps
identities is scored against the right target, not rewarded for the swap); ``assign`` -
the track the global IDF1 assignment gives it (automatic detection, whose ids are
arbitrary); ``auto`` (default for files scored on their own) - ``truth`` when every track id
is a truth id, else ``assign``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from pipeline.eval import mot, protocols
from pipeline.eval.single import (
    center_errors,
    ious,
    precision_curve,
    single_target_metrics,
    success_curve,
)
from pipeline.io.results import TrackTable, read_tracks
from pipeline.io.sequence import Truth, open_sequence

ID_RULES = ("auto", "truth", "assign")
SINGLE_KEYS = ("p5", "p20", "auc", "mean_error_px", "npr", "mpr", "msr")


def _mean(values: list[float]) -> float:
    v = [x for x in values if x is not None and not math.isnan(x)]
    return float(np.mean(v)) if v else float("nan")


def track_for_truth(
    truth_ids: list[int], tracks: TrackTable, mapping: dict[int, int], id_rule: str = "auto"
) -> dict[int, int | None]:
    """Which track id is scored against each truth id (see the module doc)."""
    if id_rule not in ID_RULES:
        raise ValueError(f"id_rule must be one of {ID_RULES}; got {id_rule!r}")
    if id_rule == "truth" or (
        id_rule == "auto" and tracks.boxes and set(tracks.boxes) <= set(truth_ids)
    ):
        return {g: (g if g in tracks.boxes else None) for g in truth_ids}
    if len(truth_ids) == 1 and len(tracks.boxes) == 1 and not mapping:
        return {truth_ids[0]: next(iter(tracks.boxes))}
    return {g: mapping.get(g) for g in truth_ids}


def evaluate(
    truth: Truth,
    tracks: TrackTable,
    n_frames: int,
    protocol: str = "default",
    id_rule: str = "auto",
    mot_rule: str = "trackeval",
    multi: bool | None = None,
) -> dict[str, object]:
    """Score ``tracks`` against ``truth`` (see the module doc for the keys).

    ``multi`` asks for the many-target scores (MOTA, IDF1, HOTA, purity, ...) even for one
    target and one track; by default they come with several targets or tracks.

    ``mot_rule`` is the CLEAR matching rule of the many-target scores: ``trackeval`` (the
    MOTChallenge numbers, default) or ``motmetrics`` (py-motmetrics'; ``pipeline.eval.mot``).
    """
    if protocol not in protocols.PROTOCOLS:
        raise ValueError(f"protocol must be one of {protocols.PROTOCOLS}; got {protocol!r}")
    if mot_rule not in mot.MATCH_RULES:
        raise ValueError(f"mot_rule must be one of {mot.MATCH_RULES}; got {mot_rule!r}")
    ch = truth.primary_channel()
    if ch is None:
        raise ValueError("the sequence has no ground truth")
    gt = truth.boxes[ch]
    other_ch = "infrared" if ch == "visible" else "visible"
    gt_other = truth.boxes.get(other_ch) if not truth.multi else None
    ids = list(gt)
    if multi is None:
        multi = truth.multi or len(ids) > 1 or len(tracks.boxes) > 1
    if truth.distractors:
        tracks = dataclasses.replace(
            tracks, boxes=mot.drop_distractor_matches(gt, tracks.boxes, truth.distractors)
        )
    data = mot.sequence_data(gt, tracks.boxes, n_frames)
    id_info = (
        mot.idf1(gt, tracks.boxes, data=data)
        if tracks.boxes
        else {"idf1": 0.0, "idp": 0.0, "idr": 0.0, "mapping": {}}
    )
    which = track_for_truth(ids, tracks, id_info["mapping"], id_rule)  # type: ignore[arg-type]
    empty = np.full((n_frames, 4), np.nan)

    per: dict[str, dict[str, float]] = {}
    for g in ids:
        t = which[g]
        pred = tracks.boxes[t] if t is not None else empty
        if protocol == "default":
            per[str(g)] = single_target_metrics(
                pred, gt[g], gt_other[g] if gt_other and g in gt_other else None
            )
        else:
            gv = truth.boxes.get("visible", {}).get(g)
            gi = truth.boxes.get("infrared", {}).get(g)
            per[str(g)] = protocols.PROTOCOL_FUNCTIONS[protocol](pred, gv, gi)
        if t is not None and t != g:
            per[str(g)]["track_id"] = t

    out: dict[str, object] = {"protocol": protocol, "channel": ch}
    keys = [
        k
        for k in next(iter(per.values()))
        if k not in ("frames", "frames_without_output", "track_id")
    ]
    if protocol == "gtot":
        pooled = [
            protocols.gtot_counts(
                tracks.boxes[which[g]] if which[g] is not None else empty,
                truth.boxes.get("visible", {}).get(g),
                truth.boxes.get("infrared", {}).get(g),
            )
            for g in ids
        ]
        frames = sum(p["frames"] for p in pooled)  # type: ignore[misc]
        pc = np.sum([p["precision_counts"] for p in pooled], axis=0).tolist()
        sc = np.sum([p["success_counts"] for p in pooled], axis=0).tolist()
        out.update(
            {k: v for k, v in protocols.gtot_from_counts(frames, pc, sc).items() if k != "frames"}
        )
    else:
        for k in keys:
            out[k] = _mean([per[str(g)].get(k, float("nan")) for g in ids])
    out["frames"] = int(sum(p.get("frames", 0) for p in per.values()))
    if multi:
        fm = mot.match_frames(gt, tracks.boxes, n_frames, rule=mot_rule, data=data)
        out.update({k: v for k, v in mot.clear_mot(fm).items()})
        out["mot_rule"] = mot_rule
        out["idf1"] = id_info["idf1"]
        out["idp"], out["idr"] = id_info["idp"], id_info["idr"]
        out["purity"] = mot.purity_matrix(gt, tracks.boxes, fm)
        out.update(mot.hota(gt, tracks.boxes, n_frames, data=data))
    out["targets"] = per
    return json_safe(out)  # type: ignore[return-value]


def json_safe(x: object) -> object:
    """``x`` with numpy scalars made Python numbers and NaN/inf made None, so it dumps as strict
    JSON."""
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if math.isfinite(float(x)) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def evaluate_files(
    seq_dir: str | Path,
    tracks_csv: str | Path,
    protocol: str = "default",
    id_rule: str = "auto",
    mot_rule: str = "trackeval",
    **open_kw: object,
) -> dict[str, object]:
    """``dualtrack evaluate SEQ_DIR TRACKS_CSV``: open the sequence, read the results, score."""
    seq = open_sequence(seq_dir, **open_kw)  # type: ignore[arg-type]
    if not seq.truth.has_truth:
        from pipeline.errors import InputError

        raise InputError(f"{seq.path} has no ground truth to evaluate against")
    tracks = read_tracks(tracks_csv, seq.n_frames)
    out = evaluate(seq.truth, tracks, seq.n_frames, protocol, id_rule, mot_rule)
    warnings = [*seq.warnings, *tracks.warnings]
    if warnings:
        out["warnings"] = warnings
    return out


def curves(
    truth: Truth, tracks: TrackTable, n_frames: int, id_rule: str = "auto"
) -> dict[int, dict[str, np.ndarray]]:
    """Per truth id: ``errors`` (N,), ``precision`` (51,), ``success`` (21,) for plots and the
    .rrd."""
    ch = truth.primary_channel()
    assert ch is not None
    gt = truth.boxes[ch]
    id_info = mot.idf1(gt, tracks.boxes) if tracks.boxes else {"mapping": {}}
    # type: ignore[arg-type]
    which = track_for_truth(list(gt), tracks, id_info["mapping"], id_rule)
    out = {}
    for g, boxes in gt.items():
        t = which[g]
        pred = tracks.boxes[t] if t is not None else np.full((n_frames, 4), np.nan)
        err = center_errors(pred, boxes)
        out[g] = {
            "errors": err,
            "precision": precision_curve(err),
            "success": success_curve(ious(pred, boxes)),
        }
    return out


__all__ = ["curves", "evaluate", "evaluate_files", "json_safe"]
