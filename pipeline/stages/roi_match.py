"""Affine-invariant correlation between two ROI chips: the image term Λ_I of the fusion paper.

The paper (its eq. 6-9) scores a track's ROI f against a detection's ROI g by the maximum,
over global affine maps U = (A, b), of their normalized cross-correlation, and finds U by
the GAT iteration (eq. 10-11). Two routes:

* :func:`ecc_match` (default): OpenCV's ECC (``cv2.findTransformECC``, ``MOTION_AFFINE``),
  which maximizes the correlation coefficient itself, seeded with the centres aligned
  (docs/algorithms.md §4.1: all 7 arguments, float32 2x3 warp, ``cv2.error`` -7 = no
  convergence, NaN checks, a flat template has no correlation). The input chip is padded
  beyond the template (:func:`roi_chips`): with equal sizes ECC failed on a 2.9 px shift
  of a smooth texture, padded it recovered 10 degrees, 5 % scale and 3 px shifts to 0.01 px;
* :func:`gat_match` (``roi_match.method = "gat"``): the paper's global affine
  transformation as docs/algorithms.md §4 reconstructs it: weighted least squares of the point
  pairs under a Gaussian window whose width is annealed, with a gradient-direction
  constraint, keeping the iterate with the best NCC.

Both return a :class:`Match`: the correlation (in [-1, 1], NaN when there is none), the warp
mapping chip-``f`` coordinates into chip-``g`` coordinates, and whether it converged.
:func:`image_likelihood` maps the correlation to the probability the association uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.params import Section, param


@dataclass(frozen=True)
class RoiMatchConfig(Section):
    """ROI image matching.

    Parameters
    ----------
    method : str
        ``ecc`` (default) or ``gat`` (the paper's route, slower).
    chip_px : int
        Chips are resampled so that their longer side has this many px, in [16, 128];
        default 48.
    margin_fraction : float
        Chips include this fraction of the ROI size around it on every side, in [0, 1];
        default 0.25.
    pad_px : int
        The detection's chip is larger than the track's by this many chip px on every
        side, so that the warped template stays inside it (ECC fails, -7 or silently, when
        it leaves the input image), in [2, 32]; default 8.
    ecc_iterations : int
        Maximum ECC iterations, >= 1; default 50.
    ecc_epsilon : float
        ECC stops when the correlation improves by less than this, > 0; default 1e-4.
    gauss_filter_px : int
        ECC's pre-smoothing kernel, odd >= 1; default 5.
    min_correlation : float
        Correlations below this give the floor likelihood, in [-1, 1]; default 0.
    sharpness : float
        Λ_I = exp(-sharpness (1 - rho)) (floored) when > 0; 0 is the paper's suggestion,
        Λ_I = max(rho, floor) (default). Affine ECC warps one blob-like shape onto another
        well enough that a wrong class still correlates at 0.8 against 0.97 for the right
        one: linearly that is 0.2 nats, too little against the state term; with 20 it is
        3.4, which the purity study needs (tools/purity_study.py). On the synthetic videos
        walking people change shape and a sharp likelihood cost identities (crossing2 IDF1
        0.97 at 0, 0.54 at 5-20), so the default stays the paper's. >= 0; default 0.
    likelihood_floor : float
        Smallest image likelihood (a failed or negative match), in (0, 1); default 0.01.
    max_scale_change : float
        A warp whose determinant differs from 1 by more than this is rejected, > 0; default 0.5.
    gat_iterations : int
        GAT iterations (the Gaussian width is annealed over them), >= 1; default 12.
    gat_points : int
        Strongest-gradient points of each chip used by GAT, >= 16; default 250.
    """

    section = "roi_match"

    method: str = param("ecc", choices=("ecc", "gat"))
    chip_px: int = param(48, ge=16, le=128)
    margin_fraction: float = param(0.25, ge=0, le=1)
    pad_px: int = param(8, ge=2, le=32)
    ecc_iterations: int = param(50, ge=1)
    ecc_epsilon: float = param(1e-4, gt=0)
    gauss_filter_px: int = param(5, ge=1, odd=True)
    min_correlation: float = param(0.0, ge=-1, le=1)
    sharpness: float = param(0.0, ge=0)
    likelihood_floor: float = param(0.01, gt=0, lt=1)
    max_scale_change: float = param(0.5, gt=0)
    gat_iterations: int = param(12, ge=1)
    gat_points: int = param(250, ge=16)


@dataclass(frozen=True)
class Match:
    """Result of matching chip f (template) against chip g."""

    correlation: float
    warp: np.ndarray  # 2x3 float32, f coordinates -> g coordinates
    converged: bool


def chip(
    frame: np.ndarray, center: tuple[float, float], size_px: tuple[int, int], scale: float
) -> np.ndarray:
    """The grey float32 chip of ``size_px`` (w, h) chip px centred on ``center`` (frame px),
    sampled at ``scale`` chip px per frame px (bilinear, replicated border)."""
    g = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    w, h = size_px
    # chip pixel (u, v) centre <- frame point center + ((u + 0.5 - w/2) / scale, ...) ; pixel
    # centres at +0.5
    M = np.array(
        [
            [scale, 0, w / 2 - scale * center[0] - 0.5 + 0.5 * scale],
            [0, scale, h / 2 - scale * center[1] - 0.5 + 0.5 * scale],
        ],
        np.float32,
    )
    return cv2.warpAffine(
        g, M, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    ).astype(np.float32)


def roi_chips(
    f_frame: np.ndarray,
    f_box: tuple[float, float, float, float],
    g_frame: np.ndarray,
    g_box: tuple[float, float, float, float],
    cfg: RoiMatchConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Template chip of ``f_box`` in ``f_frame`` and the padded input chip around ``g_box`` in
    ``g_frame``, at one scale (the template's longer side ``chip_px``), and the warp that
    aligns their centres (the ECC/GAT start)."""
    x, y, w, h = f_box
    m = cfg.margin_fraction
    ww, hh = w * (1 + 2 * m), h * (1 + 2 * m)
    s = cfg.chip_px / max(ww, hh, 1e-6)
    tw, th = max(round(ww * s), 8), max(round(hh * s), 8)
    f = chip(f_frame, (x + w / 2, y + h / 2), (tw, th), s)
    P = cfg.pad_px
    gx, gy, gw, gh = g_box
    g = chip(g_frame, (gx + gw / 2, gy + gh / 2), (tw + 2 * P, th + 2 * P), s)
    return f, g, np.array([[1, 0, P], [0, 1, P]], np.float32)


def ncc(a: np.ndarray, b: np.ndarray) -> float:
    """Normalized cross-correlation of two same-size images (mean removed, energy normalized)."""
    a = a.astype(np.float64) - a.mean()
    b = b.astype(np.float64) - b.mean()
    d = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    return float((a * b).sum() / d) if d > 1e-9 else float("nan")


def _warp_ok(W: np.ndarray, cfg: RoiMatchConfig) -> bool:
    return bool(
        np.isfinite(W).all()
        and abs(np.linalg.det(W[:, :2].astype(np.float64)) - 1) <= cfg.max_scale_change
    )


def ecc_match(
    f: np.ndarray, g: np.ndarray, cfg: RoiMatchConfig, warp0: np.ndarray | None = None
) -> Match:
    """Maximize the correlation of ``f`` warped into ``g`` over affine warps (ECC)."""
    W = np.eye(2, 3, dtype=np.float32) if warp0 is None else np.asarray(warp0, np.float32).copy()
    if float(f.std()) < 1e-3 or float(g.std()) < 1e-3:
        return Match(float("nan"), W, False)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, cfg.ecc_iterations, cfg.ecc_epsilon)
    try:
        cc, W = cv2.findTransformECC(
            f.astype(np.float32),
            g.astype(np.float32),
            W,
            cv2.MOTION_AFFINE,
            crit,
            None,
            cfg.gauss_filter_px,
        )
    except cv2.error:  # -7: did not converge (the correlation was going down)
        start = np.eye(2, 3, dtype=np.float32) if warp0 is None else np.asarray(warp0, np.float32)
        return Match(_score(f, g, start), start, False)
    if not (np.isfinite(cc) and _warp_ok(W, cfg)):
        start = np.eye(2, 3, dtype=np.float32) if warp0 is None else np.asarray(warp0, np.float32)
        return Match(_score(f, g, start), start, False)
    return Match(_score(f, g, W), W, True)


def _score(f: np.ndarray, g: np.ndarray, W: np.ndarray) -> float:
    """NCC of ``f`` and ``g`` brought into ``f``'s frame by ``W`` (over f's whole chip)."""
    h, w = f.shape
    aligned = cv2.warpAffine(
        g,
        W,
        (w, h),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return ncc(f, aligned)


def _points(img: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``n`` strongest-gradient pixels: positions relative to the centre, weights,
    directions."""
    sm = cv2.GaussianBlur(img, (5, 5), 1.0)
    gx = cv2.Sobel(sm, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(sm, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.hypot(gx, gy).ravel()
    idx = np.argsort(mag)[::-1][:n]
    h, w = img.shape
    ys, xs = np.divmod(idx, w)
    pos = np.stack([xs - (w - 1) / 2, ys - (h - 1) / 2], axis=1).astype(np.float64)
    return (
        pos,
        mag[idx].astype(np.float64),
        np.arctan2(gy.ravel()[idx], gx.ravel()[idx]).astype(np.float64),
    )


def gat_match(
    f: np.ndarray, g: np.ndarray, cfg: RoiMatchConfig, warp0: np.ndarray | None = None
) -> Match:
    """The paper's GAT correlation (docs/algorithms.md §4): anneal D, solve the weighted least
    squares ``A r1 + b ~ r2`` over point pairs, keep the iterate with the best NCC."""
    from scipy.spatial import cKDTree

    h, w = f.shape
    c_f = np.array([(w - 1) / 2, (h - 1) / 2])
    c_g = np.array([(g.shape[1] - 1) / 2, (g.shape[0] - 1) / 2])
    if float(f.std()) < 1e-3 or float(g.std()) < 1e-3:
        return Match(float("nan"), np.eye(2, 3, dtype=np.float32), False)
    p1, w1, t1 = _points(f, cfg.gat_points)
    p2, w2, t2 = _points(g, cfg.gat_points)
    w1 /= w1.max()
    w2 /= w2.max()
    tree2 = cKDTree(p2)

    def as_warp(A: np.ndarray, b: np.ndarray) -> np.ndarray:
        # r2 = A r1 + b with r relative to the chip centres -> frame coords of the chips
        t = c_g + b - A @ c_f
        return np.hstack([A, t[:, None]]).astype(np.float32)

    if warp0 is not None:
        W0 = np.asarray(warp0, np.float64)
        A, b = W0[:, :2].copy(), W0[:, :2] @ c_f + W0[:, 2] - c_g
    else:
        A, b = np.eye(2), np.zeros(2)
    best = Match(_score(f, g, as_warp(A, b)), as_warp(A, b), False)
    side = float(max(w, h))
    n = cfg.gat_iterations
    for k in range(n):
        D = side * (0.25 * (0.04 / 0.25) ** (k / max(n - 1, 1)))
        q = p1 @ A.T + b
        pairs = tree2.sparse_distance_matrix(
            cKDTree(q), max_distance=3 * D, output_type="coo_matrix"
        )
        if pairs.nnz == 0:
            break
        j, i, d = pairs.row, pairs.col, pairs.data
        rot = math.atan2(A[1, 0], A[0, 0])
        K = np.maximum(0.0, np.cos(t1[i] + rot - t2[j]))
        wt = w1[i] * w2[j] * K * np.exp(-(d * d) / (D * D))
        rs = np.bincount(
            i, weights=wt, minlength=len(p1)
        )  # row-normalize: every f point votes once
        keep = rs[i] > 0
        wt = np.where(keep, wt / np.where(rs[i] > 0, rs[i], 1), 0.0) * w1[i]
        S = wt.sum()
        if S <= 1e-12:
            break
        m1 = (wt[:, None] * p1[i]).sum(0) / S
        m2 = (wt[:, None] * p2[j]).sum(0) / S
        d1, d2 = p1[i] - m1, p2[j] - m2
        C11 = (wt[:, None, None] * d1[:, :, None] * d1[:, None, :]).sum(0)
        C21 = (wt[:, None, None] * d2[:, :, None] * d1[:, None, :]).sum(0)
        if abs(np.linalg.det(C11)) < 1e-9:
            break
        A = C21 @ np.linalg.inv(C11)
        b = m2 - A @ m1
        Wk = as_warp(A, b)
        if not _warp_ok(Wk, cfg):
            break
        sc = _score(f, g, Wk)
        if np.isfinite(sc) and (not np.isfinite(best.correlation) or sc > best.correlation):
            best = Match(sc, Wk, True)
    return best


def match_rois(
    f: np.ndarray, g: np.ndarray, cfg: RoiMatchConfig, warp0: np.ndarray | None = None
) -> Match:
    """:func:`ecc_match` or :func:`gat_match` per ``cfg.method``."""
    return (gat_match if cfg.method == "gat" else ecc_match)(f, g, cfg, warp0)


def match_boxes(
    f_frame: np.ndarray,
    f_box: tuple[float, float, float, float],
    g_frame: np.ndarray,
    g_box: tuple[float, float, float, float],
    cfg: RoiMatchConfig,
) -> Match:
    """Λ_I's correlation between a track's ROI (``f_box`` in the frame it was seen in) and a
    detection's ROI (``g_box`` in the current frame): :func:`roi_chips` then :func:`match_rois`."""
    f, g, w0 = roi_chips(f_frame, f_box, g_frame, g_box, cfg)
    return match_rois(f, g, cfg, w0)


def image_likelihood(correlation: float, cfg: RoiMatchConfig) -> float:
    """Λ_I from a correlation: ``exp(-sharpness (1 - rho))``, or ``rho`` with sharpness 0,
    never below the floor; the floor also for no match or rho below ``min_correlation``."""
    if not np.isfinite(correlation) or correlation < cfg.min_correlation:
        return cfg.likelihood_floor
    lam = (
        math.exp(-cfg.sharpness * (1.0 - float(correlation)))
        if cfg.sharpness > 0
        else float(correlation)
    )
    return max(lam, cfg.likelihood_floor)
