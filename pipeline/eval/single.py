"""Single-target metrics: centre error, precision, success, NPR, MPR/MSR.

Boxes are ``(N, 4)`` arrays of ``x, y, w, h`` (continuous 0-based px, NaN rows = no box).
Our default protocol (docs/formats.md): every frame with truth counts, frame 1 included;
a frame where the tracker gave no box has centre error ``inf`` and IoU 0; precision
counts ``error <= tau`` (inclusive); success counts ``IoU > t`` for ``t = 0, 0.05, ..., 1``
and AUC is the mean of those 21 rates.
"""

from __future__ import annotations

import numpy as np

PRECISION_THRESHOLDS_PX = np.arange(0, 51, dtype=np.float64)
SUCCESS_THRESHOLDS = np.linspace(0.0, 1.0, 21)
NPR_THRESHOLD = 0.2


def centers(boxes: np.ndarray) -> np.ndarray:
    """``(N, 2)`` centres ``(x + w/2, y + h/2)``."""
    return boxes[:, :2] + boxes[:, 2:] / 2.0


def center_errors(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-frame centre distance, px: NaN where there is no truth, inf where no prediction."""
    err = np.linalg.norm(centers(pred) - centers(gt), axis=1)
    no_pred = np.isnan(pred).any(axis=1)
    err[no_pred] = np.inf
    err[np.isnan(gt).any(axis=1)] = np.nan
    return err


def normalized_center_errors(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Centre distance with each axis divided by the truth's width/height (LasHeR's NPR)."""
    d = (centers(pred) - centers(gt)) / gt[:, 2:]
    err = np.linalg.norm(d, axis=1)
    err[np.isnan(pred).any(axis=1)] = np.inf
    err[np.isnan(gt).any(axis=1)] = np.nan
    return err


def iou_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise IoU of two ``(N, 4)`` box arrays (continuous boxes; 0 where either is NaN), in [0,
    1].

    The clip matters at the top: rounding can put identical boxes at 1 + 3e-15, which the
    success threshold ``IoU > 1`` would count."""
    x1 = np.maximum(a[:, 0], b[:, 0])
    y1 = np.maximum(a[:, 1], b[:, 1])
    x2 = np.minimum(a[:, 0] + a[:, 2], b[:, 0] + b[:, 2])
    y2 = np.minimum(a[:, 1] + a[:, 3], b[:, 1] + b[:, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    union = a[:, 2] * a[:, 3] + b[:, 2] * b[:, 3] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(union > 0, inter / union, 0.0)
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0)


def ious(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-frame IoU: NaN where there is no truth, 0 where no prediction."""
    out = iou_rows(pred, gt)
    out[np.isnan(gt).any(axis=1)] = np.nan
    return out


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(n, m)`` IoU between the rows of ``a`` (n, 4) and ``b`` (m, 4), in [0, 1]."""
    if a.shape[0] == 0 or b.shape[0] == 0:
        return np.zeros((a.shape[0], b.shape[0]))
    ax1, ay1 = a[:, 0:1], a[:, 1:2]
    ax2, ay2 = ax1 + a[:, 2:3], ay1 + a[:, 3:4]
    bx1, by1 = b[:, 0], b[:, 1]
    bx2, by2 = bx1 + b[:, 2], by1 + b[:, 3]
    iw = np.clip(np.minimum(ax2, bx2) - np.maximum(ax1, bx1), 0, None)
    ih = np.clip(np.minimum(ay2, by2) - np.maximum(ay1, by1), 0, None)
    inter = iw * ih
    union = (a[:, 2] * a[:, 3])[:, None] + (b[:, 2] * b[:, 3])[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.clip(np.where(union > 0, inter / union, 0.0), 0.0, 1.0)


def precision_curve(
    errors: np.ndarray, thresholds: np.ndarray = PRECISION_THRESHOLDS_PX
) -> np.ndarray:
    """Fraction of frames (with truth) whose error is ``<= tau``, per threshold."""
    e = errors[~np.isnan(errors)]
    if e.size == 0:
        return np.full(thresholds.shape, np.nan)
    return (e[None, :] <= thresholds[:, None]).mean(axis=1)


def success_curve(overlaps: np.ndarray, thresholds: np.ndarray = SUCCESS_THRESHOLDS) -> np.ndarray:
    """Fraction of frames (with truth) whose IoU is ``> t``, per threshold."""
    o = overlaps[~np.isnan(overlaps)]
    if o.size == 0:
        return np.full(thresholds.shape, np.nan)
    return (o[None, :] > thresholds[:, None]).mean(axis=1)


def _frac(x: np.ndarray, pred) -> float:
    x = x[~np.isnan(x)]
    return float(pred(x).mean()) if x.size else float("nan")


def single_target_metrics(
    pred: np.ndarray,
    gt: np.ndarray,
    gt_other: np.ndarray | None = None,
    err: np.ndarray | None = None,
    ov: np.ndarray | None = None,
) -> dict[str, float]:
    """Default-protocol metrics of one target.

    Parameters
    ----------
    pred : (N, 4)
        Tracker boxes (NaN rows where it gave none).
    gt : (N, 4)
        Truth of the scored channel (visible when both channels have truth).
    gt_other : (N, 4), optional
        Truth of the other channel, for MPR/MSR (per frame the smaller centre error /
        larger IoU of the two channels).
    err, ov : (N,), optional
        :func:`center_errors` and :func:`ious` of ``pred`` and ``gt`` where the caller has
        them already.

    Returns
    -------
    dict with ``p5``, ``p20``, ``auc``, ``mean_error_px``, ``npr``, ``frames`` (frames
    with truth), ``frames_without_output``, and ``mpr``, ``msr`` when ``gt_other`` is given.
    """
    err = center_errors(pred, gt) if err is None else err
    ov = ious(pred, gt) if ov is None else ov
    nerr = normalized_center_errors(pred, gt)
    valid = ~np.isnan(err)
    finite = err[valid & np.isfinite(err)]
    out = {
        "p5": _frac(err, lambda e: e <= 5.0),
        "p20": _frac(err, lambda e: e <= 20.0),
        "auc": float(np.mean(success_curve(ov))) if valid.any() else float("nan"),
        "mean_error_px": float(finite.mean()) if finite.size else float("nan"),
        "npr": _frac(nerr, lambda e: e <= NPR_THRESHOLD),
        "frames": int(valid.sum()),
        "frames_without_output": int((valid & np.isinf(err)).sum()),
    }
    if gt_other is not None:
        e2 = center_errors(pred, gt_other)
        o2 = ious(pred, gt_other)
        emin = np.fmin(err, e2)  # fmin ignores a NaN on one side
        omax = np.fmax(ov, o2)
        out["mpr"] = _frac(emin, lambda e: e <= 20.0)
        out["msr"] = (
            float(np.mean(success_curve(omax))) if (~np.isnan(omax)).any() else float("nan")
        )
    return out
