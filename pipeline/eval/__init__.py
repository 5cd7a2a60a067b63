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
from pipeline.types import BBox, FrameResult, FrameTruth, TruthMatch

ID_RULES = ("auto", "truth", "assign")
MIN_VISIBILITY = 0.25
"""Visibility from which a truth box counts in the ``*_visible`` scores (fraction of the target
not hidden, from ``gt.txt``'s visibility column; synthetic scenes write it)."""
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


class Assessment:
    """One evaluation of a run against its truth, computed once: which track each truth id is
    scored against, every target's per-frame centre errors and IoUs, the identity assignment
    and the many-target frame data; the metrics (:meth:`metrics`), the plots' curves
    (:meth:`curves`) and the per-attribute counts are all read from it.

    Parameters
    ----------
    truth : Truth
        The sequence's truth (the scored channel is the visible one when both have truth).
    tracks : TrackTable
        The run's boxes per track id.
    n_frames : int
        Frames scored (the first ``n_frames`` of the sequence).
    id_rule : {"auto", "truth", "assign"}
        Which track is scored against which truth id (module doc).

    Examples
    --------
    >>> import numpy as np
    >>> from pipeline.io.results import TrackTable
    >>> from pipeline.io.sequence import Truth
    >>> gt = {1: np.array([[0, 0, 10, 10], [2, 0, 10, 10.0]])}
    >>> shifted = TrackTable({1: gt[1] + [3, 3, 0, 0]}, {})  # 3 px right and down
    >>> a = Assessment(Truth({"visible": gt}, {}, {}, False), shifted, 2)
    >>> a.errors[1].round(2).tolist(), a.metrics()["p5"]
    ([4.24, 4.24], 1.0)
    """

    def __init__(self, truth: Truth, tracks: TrackTable, n_frames: int, id_rule: str = "auto"):
        if id_rule not in ID_RULES:
            raise ValueError(f"id_rule must be one of {ID_RULES}; got {id_rule!r}")
        ch = truth.primary_channel()
        if ch is None:
            raise ValueError("the sequence has no ground truth")
        self.truth, self.n_frames, self.id_rule, self.channel = truth, n_frames, id_rule, ch
        self.gt = truth.boxes[ch]
        self.ids = list(self.gt)
        if truth.distractors:  # boxes on a distractor are neither true nor false positives
            boxes = mot.drop_distractor_matches(self.gt, tracks.boxes, truth.distractors)
            tracks = dataclasses.replace(tracks, boxes=boxes)
        self.tracks = tracks
        # the many-target scores count the annotated frames only: with sparse truth (VTUAV: every
        # 10th frame) a track's box on a frame nobody annotated is neither right nor wrong
        keep = truth.annotated(n_frames)
        self.mot_gt = {g: b[:n_frames][keep] for g, b in self.gt.items()}
        self.mot_tracks = {t: b[:n_frames][keep] for t, b in tracks.boxes.items()}
        self.mot_frames = int(keep.sum())
        self.data = mot.sequence_data(self.mot_gt, self.mot_tracks, self.mot_frames)
        self.id_info = (
            mot.idf1(self.mot_gt, self.mot_tracks, data=self.data)
            if tracks.boxes
            else {"idf1": 0.0, "idp": 0.0, "idr": 0.0, "mapping": {}}
        )
        self.which = track_for_truth(self.ids, tracks, self.id_info["mapping"], id_rule)
        self.errors = {g: center_errors(self.pred(g), self.gt[g]) for g in self.ids}
        self.overlaps = {g: ious(self.pred(g), self.gt[g]) for g in self.ids}

    def pred(self, g: int) -> np.ndarray:
        """The boxes scored against truth id ``g`` (NaN rows where there are none)."""
        t = self.which[g]
        return self.tracks.boxes[t] if t is not None else np.full((self.n_frames, 4), np.nan)

    def multi(self) -> bool:
        """Whether the many-target scores apply: several targets or tracks, or a MOT truth."""
        return self.truth.multi or len(self.ids) > 1 or len(self.tracks.boxes) > 1

    def metrics(
        self, protocol: str = "default", mot_rule: str = "trackeval", multi: bool | None = None
    ) -> dict[str, object]:
        """The ``evaluate --json`` object (module doc) under ``protocol``; ``multi`` asks for
        the many-target scores even for one target and one track."""
        if protocol not in protocols.PROTOCOLS:
            raise ValueError(f"protocol must be one of {protocols.PROTOCOLS}; got {protocol!r}")
        if mot_rule not in mot.MATCH_RULES:
            raise ValueError(f"mot_rule must be one of {mot.MATCH_RULES}; got {mot_rule!r}")
        per = {str(g): self._target(g, protocol) for g in self.ids}
        out: dict[str, object] = {"protocol": protocol, "channel": self.channel}
        if protocol == "gtot":
            out.update(self._gtot_pooled())
        else:
            skip = ("frames", "frames_without_output", "track_id")
            for k in (k for k in next(iter(per.values())) if k not in skip):
                out[k] = _mean([per[str(g)].get(k, float("nan")) for g in self.ids])
        out["frames"] = int(sum(p.get("frames", 0) for p in per.values()))
        if self.multi() if multi is None else multi:
            out.update(self._many(mot_rule))
        out["targets"] = per
        return json_safe(out)  # type: ignore[return-value]

    def _target(self, g: int, protocol: str) -> dict[str, float]:
        """Truth id ``g``'s scores under ``protocol`` (and the track scored, when not ``g``)."""
        pred = self.pred(g)
        if protocol == "default":
            other = "infrared" if self.channel == "visible" else "visible"
            gt_other = None if self.truth.multi else self.truth.boxes.get(other, {}).get(g)
            out = single_target_metrics(
                pred, self.gt[g], gt_other, err=self.errors[g], ov=self.overlaps[g]
            )
        else:
            gv = self.truth.boxes.get("visible", {}).get(g)
            gi = self.truth.boxes.get("infrared", {}).get(g)
            out = protocols.PROTOCOL_FUNCTIONS[protocol](pred, gv, gi)
        t = self.which[g]
        if t is not None and t != g:
            out["track_id"] = t
        return out

    def gtot_counts(self) -> dict[str, object]:
        """GTOT's hit counts of every target, pooled (``frames``, ``precision_counts``,
        ``success_counts``)."""
        pooled = [
            protocols.gtot_counts(
                self.pred(g),
                self.truth.boxes.get("visible", {}).get(g),
                self.truth.boxes.get("infrared", {}).get(g),
            )
            for g in self.ids
        ]
        return {
            "frames": sum(int(p["frames"]) for p in pooled),
            "precision_counts": np.sum([p["precision_counts"] for p in pooled], axis=0),
            "success_counts": np.sum([p["success_counts"] for p in pooled], axis=0),
        }

    def _gtot_pooled(self) -> dict[str, object]:
        c = self.gtot_counts()
        pooled = protocols.gtot_from_counts(
            c["frames"], c["precision_counts"].tolist(), c["success_counts"].tolist()
        )
        return {k: v for k, v in pooled.items() if k != "frames"}

    def _many(self, mot_rule: str) -> dict[str, object]:
        """CLEAR-MOT, IDF1, purity and HOTA, on the annotated frames."""
        gt, boxes, n = self.mot_gt, self.mot_tracks, self.mot_frames
        fm = mot.match_frames(gt, boxes, n, rule=mot_rule, data=self.data)
        out: dict[str, object] = dict(mot.clear_mot(fm))
        out["mot_rule"] = mot_rule
        out["idf1"] = self.id_info["idf1"]
        out["idp"], out["idr"] = self.id_info["idp"], self.id_info["idr"]
        out["purity"] = mot.purity_matrix(gt, boxes, fm)
        out.update(mot.hota(gt, boxes, n, data=self.data))
        out.update(self._visible_scores(mot_rule))
        if n < self.n_frames:
            out["mot_frames"] = n  # the annotated frames the scores above count
        return out

    def _visible_scores(self, mot_rule: str) -> dict[str, object]:
        """``idf1_visible`` and ``purity_visible``: IDF1 and overall purity on the frames where
        each target is at least :data:`MIN_VISIBILITY` visible (the all-frames figures when every
        truth box is); {} without a visibility column.

        A less visible truth box is an ignore region, as MOTChallenge scores its visibility
        filter: the box leaves the truth, and a track box that overlaps it (IoU >= 0.5, one
        box per box) is neither a true nor a false positive. A tracker that keeps a hidden
        target's identity is then scored on the frames where it can be seen."""
        keep = self.truth.annotated(self.n_frames)
        vis = {g: v[: self.n_frames][keep] for g, v in self.truth.visibility.items()}
        low = {
            g: (vis[g] < MIN_VISIBILITY) & ~np.isnan(b).any(axis=1)
            for g, b in self.mot_gt.items()
            if g in vis
        }
        if not low:
            return {}
        gt, ignored = {}, {}
        for g, b in self.mot_gt.items():
            m = low.get(g, np.zeros(len(b), bool))
            gt[g] = np.where(m[:, None], np.nan, b)
            if m.any():
                ignored[g] = np.where(m[:, None], b, np.nan)
        tracks = mot.drop_distractor_matches(gt, self.mot_tracks, ignored)
        n = self.mot_frames
        data = mot.sequence_data(gt, tracks, n)
        fm = mot.match_frames(gt, tracks, n, rule=mot_rule, data=data)
        ids = mot.idf1(gt, tracks, data=data)["idf1"] if tracks else 0.0
        kept = sum(int((~np.isnan(b).any(axis=1)).sum()) for b in gt.values())
        return {
            "idf1_visible": ids,
            "purity_visible": mot.purity_matrix(gt, tracks, fm)["overall"],
            "visible_target_frames": kept,
        }

    def curves(self) -> dict[int, dict[str, np.ndarray]]:
        """Per truth id: ``errors`` (N,), ``precision`` (51,), ``success`` (21,), for the plots."""
        return {
            g: {
                "errors": self.errors[g],
                "precision": precision_curve(self.errors[g]),
                "success": success_curve(self.overlaps[g]),
            }
            for g in self.ids
        }


def frame_truth(truth: Truth, result: FrameResult) -> FrameTruth:
    """The truth of one frame per channel, and each target's centre error, IoU and truth match
    against the scored channel's truth, by the formulas of :class:`Assessment` (a recording
    streams them while the run goes, so they are computed frame by frame; ids as in the truth,
    a target not reported scores as a failure: error ``inf``, IoU 0).

    Examples
    --------
    >>> import numpy as np
    >>> from pipeline.io.sequence import Truth
    >>> from pipeline.types import BBox, FrameResult, TargetResult, TargetStatus
    >>> truth = Truth({"visible": {1: np.array([[0, 0, 10, 10.0]])}}, {}, {}, False)
    >>> r = FrameResult(1, (TargetResult(1, BBox(3, 4, 10, 10), TargetStatus.TRACKING, "x"),))
    >>> ft = frame_truth(truth, r)
    >>> ft.center_error_px[1], round(ft.iou[1], 3), ft.match[1].value
    (5.0, 0.266, 'overlap')
    """
    i = result.frame - 1
    boxes = {
        ch: {tid: BBox(*b[i]) for tid, b in table.items() if not _has_nan(b[i])}
        for ch, table in truth.boxes.items()
    }
    ch = truth.primary_channel()
    scored = truth.boxes.get(ch, {}) if ch is not None else {}
    err, iou, match = {}, {}, {}
    for t in result.targets:
        gt = scored.get(t.id)
        if gt is None:
            continue
        g = gt[i].tolist()
        if any(math.isnan(v) for v in g):
            match[t.id] = TruthMatch.NO_TRUTH
            continue
        if t.status.is_reported and not any(math.isnan(v) for v in t.box.as_tuple()):
            err[t.id], iou[t.id] = _error_and_iou(tuple(float(v) for v in t.box.as_tuple()), g)
        else:  # not reported: a failure (center_errors' inf, ious' 0)
            err[t.id], iou[t.id] = math.inf, 0.0
        match[t.id] = TruthMatch.OVERLAP if iou[t.id] > 0 else TruthMatch.FAILURE
    return FrameTruth(boxes, err, iou, match)


def _has_nan(row: np.ndarray) -> bool:
    return any(math.isnan(v) for v in row.tolist())


def _error_and_iou(p: tuple[float, ...], g: list[float]) -> tuple[float, float]:
    """:func:`center_errors` and :func:`ious` of one box pair without NaN, in Python floats: the
    same float64 operations in the same order, so the same values (tested); a frame's numpy
    calls on 1-row arrays cost more than the rest of its evaluation."""
    dx = (p[0] + p[2] / 2.0) - (g[0] + g[2] / 2.0)
    dy = (p[1] + p[3] / 2.0) - (g[1] + g[3] / 2.0)
    e = math.sqrt(dx * dx + dy * dy)
    x1, y1 = max(p[0], g[0]), max(p[1], g[1])
    x2, y2 = min(p[0] + p[2], g[0] + g[2]), min(p[1] + p[3], g[1] + g[3])
    inter = max(x2 - x1, 0.0) * max(y2 - y1, 0.0)
    union = p[2] * p[3] + g[2] * g[3] - inter
    v = inter / union if union > 0 else 0.0
    return e, min(max(v, 0.0), 1.0)


def evaluate(
    truth: Truth,
    tracks: TrackTable,
    n_frames: int,
    protocol: str = "default",
    id_rule: str = "auto",
    mot_rule: str = "trackeval",
    multi: bool | None = None,
) -> dict[str, object]:
    """Score ``tracks`` against ``truth``: ``Assessment(...).metrics(...)`` (the module doc
    lists the keys).

    ``multi`` asks for the many-target scores (MOTA, IDF1, HOTA, purity, ...) even for one
    target and one track; by default they come with several targets or tracks. ``mot_rule`` is
    the CLEAR matching rule of the many-target scores: ``trackeval`` (the MOTChallenge numbers,
    default) or ``motmetrics`` (py-motmetrics'; ``pipeline.eval.mot``).
    """
    return Assessment(truth, tracks, n_frames, id_rule).metrics(protocol, mot_rule, multi)


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
    results_base: float | None = None,
    **open_kw: object,
) -> dict[str, object]:
    """``dualtrack evaluate SEQ_DIR TRACKS_CSV``: open the sequence, read the results, score them.

    Exported as ``pipeline.evaluate``.

    Parameters
    ----------
    seq_dir : str or Path
        The sequence folder, with its ground truth.
    tracks_csv : str or Path
        A results file: MOTChallenge rows ``frame,id,x,y,w,h,...`` (1-based), as ``tracks.csv``
        of a run folder, or one ``x,y,w,h`` per frame.
    protocol : {"default", "gtot", "rgbt234", "lasher", "vtuav"}
        Our rules, or a toolkit's own (module doc).
    id_rule : {"auto", "truth", "assign"}
        Which track is scored against which truth id (module doc).
    mot_rule : {"trackeval", "motmetrics"}
        The CLEAR matching rule of the many-target scores.
    results_base : {0, 1}, optional
        The results file's coordinate base; default 1 for MOT rows, 0 for a per-frame box
        file (``--results-base``).
    **open_kw
        Passed to :func:`~pipeline.io.sequence.open_sequence` (``channel``, ``align``,
        ``gt_base``).

    Returns
    -------
    dict
        The ``evaluate --json`` object: ``p5``, ``p20``, ``auc``, ``mean_error_px``, ``npr``
        (``mpr``, ``msr`` with truth in both channels), the many-target scores with several
        targets, ``targets`` per truth id, and ``warnings`` about the input when there are any.

    Raises
    ------
    InputError
        No such folder, no ground truth, or an unreadable results file.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from pipeline import evaluate, synthesize_random
    >>> scene = synthesize_random(Path(tempfile.mkdtemp()) / "s", seed=3, targets=1, frames=30,
    ...                           progress=False)
    >>> truth = (scene / "visible.txt").read_text().splitlines()  # x,y,w,h per frame, 0-based
    >>> rows = [f"{k + 1},1," + ",".join(str(float(v) + (1 if i < 2 else 0))
    ...         for i, v in enumerate(line.split(","))) + ",1,-1,-1,-1"
    ...         for k, line in enumerate(truth)]  # the truth itself, as 1-based MOT rows
    >>> _ = (scene / "perfect.csv").write_text(chr(10).join(rows))
    >>> m = evaluate(scene, scene / "perfect.csv")
    >>> m["p20"], m["auc"] > 0.95
    (1.0, True)
    """
    seq = open_sequence(seq_dir, **open_kw)  # type: ignore[arg-type]
    if not seq.truth.has_truth:
        from pipeline.errors import InputError

        raise InputError(f"{seq.path} has no ground truth to evaluate against")
    tracks = read_tracks(tracks_csv, seq.n_frames, results_base)
    out = evaluate(seq.truth, tracks, seq.n_frames, protocol, id_rule, mot_rule)
    warnings = [*seq.warnings, *tracks.warnings]
    if warnings:
        out["warnings"] = warnings
    return out


def curves(
    truth: Truth, tracks: TrackTable, n_frames: int, id_rule: str = "auto"
) -> dict[int, dict[str, np.ndarray]]:
    """Per truth id: ``errors`` (N,), ``precision`` (51,), ``success`` (21,):
    ``Assessment(...).curves()``."""
    return Assessment(truth, tracks, n_frames, id_rule).curves()


__all__ = ["Assessment", "curves", "evaluate", "evaluate_files", "frame_truth", "json_safe"]
