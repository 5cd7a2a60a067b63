"""CamShift pieces (Bradski 1998; OpenCV's ``cv2.CamShift``) as pure functions.

The appearance is a 1-D histogram: hue (OpenCV 0..179, pixels of low saturation or
brightness masked out) in visible frames, intensity in infrared frames. Back-projection
is a numpy lookup (never the 3-D ``calcBackProject`` path; docs/algorithms.md §7.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.types import BBox


@dataclass(frozen=True)
class Feature:
    """Per-pixel bin index (uint8) and validity mask (bool) of an image region."""

    bins: np.ndarray
    valid: np.ndarray
    n_bins: int


_LUTS: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}


def _hue_sat_luts(n_hue: int, n_sat: int) -> tuple[np.ndarray, np.ndarray]:
    key = (n_hue, n_sat)
    if key not in _LUTS:
        v = np.arange(256)
        lut_h = (np.minimum(v * n_hue // 180, n_hue - 1) * n_sat).astype(np.uint8)
        lut_s = (v * n_sat // 256).astype(np.uint8)
        _LUTS[key] = (lut_h, lut_s)
    return _LUTS[key]


def to_hsv(image: np.ndarray) -> np.ndarray:
    """OpenCV 8-bit HSV of a BGR image (H 0..179)."""
    return cv2.cvtColor(image, cv2.COLOR_BGR2HSV)


def feature(
    image: np.ndarray,
    n_bins: int,
    min_saturation: int = 60,
    min_value: int = 32,
    saturation_bins: int = 1,
    hsv: np.ndarray | None = None,
) -> Feature:
    """Hue bins (visible BGR; times ``saturation_bins`` saturation bins) or intensity bins (IR
    grey).

    Visible pixels below ``min_saturation`` or ``min_value`` are invalid (hue is meaningless
    there). Pass ``hsv`` (from :func:`to_hsv`) to reuse one conversion for several features.
    """
    if n_bins * saturation_bins > 256:
        raise ValueError(f"at most 256 bins; got {n_bins} x {saturation_bins}")
    if image.ndim == 3:
        if hsv is None:
            hsv = to_hsv(image)
        lut_h, lut_s = _hue_sat_luts(n_bins, saturation_bins)
        bins = cv2.add(cv2.LUT(hsv[..., 0], lut_h), cv2.LUT(hsv[..., 1], lut_s))
        valid = (hsv[..., 1] >= min_saturation) & (hsv[..., 2] >= min_value)
        return Feature(bins, valid, n_bins * saturation_bins)
    lut = (np.arange(256) * n_bins // 256).astype(np.uint8)
    return Feature(cv2.LUT(image, lut), np.ones(image.shape, bool), n_bins)


def histogram(f: Feature, mask: np.ndarray | None = None) -> np.ndarray:
    """Normalized histogram of the valid pixels (inside ``mask``); zeros when none."""
    sel = f.valid if mask is None else (f.valid & mask)
    h = np.bincount(f.bins[sel], minlength=f.n_bins).astype(np.float64)
    s = h.sum()
    return h / s if s > 0 else h


def kernel_masked_histogram(f: Feature, box: BBox) -> np.ndarray:
    """Epanechnikov-weighted histogram of the valid pixels of the ellipse inscribed in ``box``.

    Border pixels count little, so a box next to a same-coloured occluder is judged mostly
    by what lies at its centre.
    """
    from pipeline.stages.histogram import ellipse_histogram

    if box.w <= 0 or box.h <= 0:
        raise ValueError(f"half-axes must be positive; got ({box.w / 2.0}, {box.h / 2.0})")
    h = ellipse_histogram(
        f.bins, float(box.cx), float(box.cy), box.w / 2.0, box.h / 2.0, f.n_bins, f.valid
    )[0]
    s = h.sum()
    return h / s if s > 0 else h


def sampling_distance(f: Feature, box: BBox) -> float:
    """The Bhattacharyya distance that sampling noise alone puts between two histograms of the
    target in ``box`` (:func:`kernel_masked_histogram`): the distance between the histograms of
    its pixels on the two colours of a checkerboard, over sqrt(2) (each half has half the
    pixels, and the distance's square goes as 1 / pixels). About 0.1 for a target of a few
    thousand pixels, 0.4 and more for one of under a hundred.
    """
    from pipeline.stages.histogram import bhattacharyya, bhattacharyya_distance

    yy, xx = np.indices(f.valid.shape)
    even = (yy + xx) % 2 == 0
    halves = [
        kernel_masked_histogram(Feature(f.bins, f.valid & m, f.n_bins), box) for m in (even, ~even)
    ]
    if any(h.sum() <= 0 for h in halves):
        return 1.0
    return bhattacharyya_distance(bhattacharyya(halves[0], halves[1])) / math.sqrt(2.0)


def background_weights(f: Feature, box: BBox, scale: float) -> np.ndarray:
    """Per-bin weights ``v_u = min(o* / o_u, 1)`` of the corrected background-weighted histogram
    (Ning, Zhang, Zhang, Wu 2012): ``o`` the histogram of the surround, the pixels of ``box``
    scaled ``scale`` times (clipped to the image) outside the ellipse of ``box`` scaled 1.2 times,
    and ``o*`` its smallest non-zero bin. A bin absent from the surround keeps weight 1; ones when
    the surround is empty."""
    H, W = f.bins.shape
    big = box.scaled(scale).clip(W, H)
    ring = np.zeros((H, W), bool)
    ring[int(big.y) : math.ceil(big.y2), int(big.x) : math.ceil(big.x2)] = True
    ring &= ~box_mask((H, W), box.scaled(1.2))
    o = histogram(f, ring)
    nz = o[o > 0]
    if nz.size == 0:
        return np.ones(f.n_bins)
    return np.where(o > 0, np.minimum(nz.min() / np.maximum(o, 1e-300), 1.0), 1.0)


def weighted_model(q: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``q`` times ``weights``, normalised (``q`` itself when nothing is left)."""
    w = q * weights
    s = w.sum()
    return w / s if s > 0 else q


def back_project(f: Feature, hist: np.ndarray) -> np.ndarray:
    """uint8 probability image: the histogram scaled to max 255, looked up per pixel (0 where
    invalid)."""
    peak = hist.max()
    lut = np.zeros(256, np.uint8)
    if peak > 0:
        lut[: f.n_bins] = np.round(hist * (255.0 / peak)).astype(np.uint8)
    prob = cv2.LUT(f.bins, lut)
    if not f.valid.all():
        prob[~f.valid] = 0
    return prob


def box_mask(shape: tuple[int, int], box: BBox) -> np.ndarray:
    """Boolean mask of the ellipse inscribed in ``box`` (px of an image of ``shape``)."""
    m = np.zeros(shape[:2], np.uint8)
    c = (round(box.cx * 4), round(box.cy * 4))
    ax = (max(round(box.w * 2), 1), max(round(box.h * 2), 1))
    cv2.ellipse(m, c, ax, 0, 0, 360, 1, -1, cv2.LINE_8, shift=2)
    return m.astype(bool)


@dataclass(frozen=True)
class CamShiftResult:
    """``box``: axis-aligned bound of the CamShift ellipse (None when nothing was found);
    ``window`` the search window OpenCV returns; ``area_px2`` = box area (0 when nothing was
    found)."""

    box: BBox | None
    window: BBox
    area_px2: float
    iterations_cap: int


def camshift(
    prob: np.ndarray, window: BBox, max_iterations: int = 10, epsilon_px: float = 1.0
) -> CamShiftResult:
    """Run ``cv2.CamShift`` from ``window`` (px of ``prob``); degenerate results give
    ``box=None``."""
    h, w = prob.shape
    win = window.to_cv(w, h)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, max_iterations, epsilon_px)
    rot, new_win = cv2.CamShift(prob, win, crit)
    (cx, cy), (rw, rh), _ = rot
    if not np.isfinite([cx, cy, rw, rh]).all() or rw < 1 or rh < 1:
        return CamShiftResult(None, BBox(*map(float, new_win)), 0.0, max_iterations)
    bx, by, bw, bh = cv2.boundingRect(cv2.boxPoints(rot).astype(np.float32))
    box = BBox(float(bx), float(by), float(bw), float(bh)).clip(w, h)
    if box.w < 1 or box.h < 1:
        return CamShiftResult(None, BBox(*map(float, new_win)), 0.0, max_iterations)
    return CamShiftResult(box, BBox(*map(float, new_win)), box.area, max_iterations)
