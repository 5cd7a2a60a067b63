"""A spatial appearance cue: a discriminative correlation filter learned online over both channels.

This is the DCF of the MOSSE / DSST family (Bolme et al. 2010; Danelljan et al. 2014, 2017),
written on SciPy's FFTs, with the per-cell work (features, correlation, peak) in compiled
kernels:

* **Features** (:func:`features`): on a window around the target, resized so that it holds
  ``template_cells`` cells of ``cell_px`` px along its longer side, per cell a histogram of
  gradient orientations (``hog_bins`` unsigned bins, magnitude-weighted, normalised by the
  energy of the 3 x 3 cells around it and clipped, as HOG does) of the visible frame's
  luminance, the cell's mean colour (CIELAB a*, b*) and luminance, and the same gradient
  histogram and the mean intensity of the infrared frame. A channel the sequence lacks, or
  the visible colour in the dark, is simply left out (its weight, ``channel_weights``, is
  zero).
* **Translation filter**: per channel l, ``A_l = conj(G) F_l`` and ``B = sum_l |F_l|^2`` over
  the cosine-windowed features' spectra (``G`` the spectrum of a Gaussian label peaked on the
  target); the response to new features ``Z`` is ``ifft(sum_l conj(A_l) Z_l / (B + lambda))``
  and its peak, refined to sub-cell precision, is the target's displacement. The quality of
  a detection is its peak-to-sidelobe ratio (PSR).
* **Scale filter** (DSST): the target cropped at ``scale_count`` scales around its size, each
  resized to a fixed small template and described by the same features, flattened into one
  column per scale; a one-dimensional filter over the scales gives the size change.
* **Update**: ``A`` and ``B`` are blended with the new frame's at a learning rate the caller
  chooses per frame (the tracker's selective update gates it: occlusions do not teach the
  filter).

Coordinates are frame px; a :class:`AppearanceModel` is immutable and every function here
is pure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cache

import cv2
import numba
import numpy as np
import scipy.fft as fft

try:  # SciPy's own FFT engine, called without scipy.fft's per-call dispatch (same results)
    from scipy.fft._pocketfft import pypocketfft as _pocketfft
except ImportError:  # pragma: no cover (a SciPy without it: its public functions)
    _pocketfft = None

from pipeline.params import Section, param
from pipeline.types import BBox


@dataclass(frozen=True)
class AppearanceConfig(Section):
    """The correlation-filter appearance cue.

    Parameters
    ----------
    cell_px : int
        Side of a feature cell in template px, in [2, 8]; default 4.
    padding : float
        The search window is the target size times ``1 + padding`` per side, in [0.5, 4];
        default 1.5. Increasing it tolerates faster motion and brings more background into
        the filter.
    template_cells : int
        Cells along the window's longer side (the window is resized to this), in [8, 64];
        default 24. The cost grows with its square, not with the target's size.
    lambda_reg : float
        Regularisation of the filter's denominator, > 0; default 1e-2.
    label_sigma_factor : float
        Width of the Gaussian label, as a share of the target's size in cells, in (0, 1];
        default 0.1 (KCF/DSST).
    learning_rate : float
        Default blending weight of a new frame into the filter, in [0, 1]; default 0.02.
        Increasing it follows appearance changes faster and forgets the target faster when
        something covers it.
    hog_bins : int
        Unsigned gradient-orientation bins per cell, in [4, 18]; default 9.
    hog_clip : float
        Normalised histogram values are clipped at this, in (0, 1]; default 0.2 (HOG).
    colour : bool
        Use the visible frame's colour (a*, b*) and luminance per cell; default True.
    colour_weight : float
        Weight of the a*, b* channels against the gradient histograms, >= 0; default 3.
        Gradients alone tell two people or two cars apart badly (their shapes are alike,
        above all in IR); colour is what differs, and a cast shadow changes the luminance
        far more than a* and b*.
    balance_groups : bool
        Scale the feature groups (visible gradients, visible colour, IR gradients, IR
        intensity) to the same energy in the first frame's window, so that a faint IR target
        or a dull colour still counts; default True.
    intensity_clip : float
        With ``balance_groups``, the colour and IR intensity features are clipped at this many
        times their first-frame rms, >= 0 (0: no clipping); default 2.5. A neighbour far
        hotter or brighter than the target then cannot draw the filter by its energy alone.
    visible_gradients : bool
        Use the visible frame's gradient histogram; default True.
    infrared : bool
        Use the infrared frame's gradient histogram and intensity; default True.
    scale_filter : bool
        Estimate the size with a scale filter (DSST); default True. False keeps the size the
        caller gives and saves about 40 % of the filter's cost.
    scale_channels : str
        Where both frames exist, the scale filter's gradients come from ``infrared``,
        ``visible``, ``both`` or ``adaptive``; default ``adaptive``. ``adaptive`` starts on
        the infrared and moves the scale filter to the frame that shows the target better:
        where the translation filter's visible PSR has run at ``scale_switch_ratio`` times its
        IR PSR (a running geometric mean over the learning frames) the scale filter is learned
        afresh on the visible frame, and back on the infrared once the IR's PSR has caught up.
        It reads one frame's gradients, as ``infrared`` does; ``both`` reads the two and
        doubles the scale filter's cost.
    scale_switch_ratio : float
        With ``adaptive``, the ratio of the visible to the IR PSR at which the scale filter
        moves to the visible frame, > 1; default 2. Increasing it moves fewer targets (at 3
        almost none on the development range).
    scale_count : int
        Scales of the scale filter (odd), in [3, 33]; default 13. Increasing it finds large
        size changes per frame and costs one small crop and feature pass per scale.
    scale_step : float
        Ratio between neighbouring scales, in (1, 1.2]; default 1.03.
    scale_template_px : int
        Each scale's crop is resized so that its area is this squared, px, in [16, 64];
        default 32.
    scale_learning_rate : float
        Default blending weight of the scale filter, in [0, 1]; default 0.025.
    max_scale_change : float
        The size estimate moves at most this factor per frame, > 1; default 1.1.
    update_every_frames : int
        The tracker blends a frame into the filter every this many frames, at the learning
        rate compounded over them (ECO's sparse update), >= 1; default 1. Increasing it
        saves the cost of learning and makes the filter slower to follow a change.
    scale_every_frames : int
        The tracker estimates the scale, and blends a frame into the scale filter (at the rate
        compounded over them), every this many frames, >= 1; default 1. Increasing it saves most of
        the scale filter's cost (about a fifth of the tracker's) and follows a size change later.
    scale_reuse_px : float
        The scale filter learns from the samples its detection took this frame, moved along
        the scales to the learned box's size (linear between neighbouring scales), when that
        box's centre lies within this many px of the detection's and its size within one
        scale step, >= 0; default 1; 0 takes the samples again at the learned box. It saves the
        second of the two passes over the scales on most frames (about 5 % of the tracker's
        time); the samples it learns are off by up to that distance and by the interpolation.
    anchor_every_frames : int
        Every this many frames the tracker checks the size against the target's first filter
        (:func:`anchor_factor`), >= 0; default 5 (0: off). The scale filter learns each frame
        at the size it estimated, so a size that lags a slow growth (an approaching walker,
        0.5 % a frame, under a tenth of a scale step) is learned as the target's and never
        caught up: the first frame's translation filter, which has learned nothing since,
        peaks higher at the size the target has. Lowering it follows a growth sooner and
        costs three translation detections a check. The dual tracker checks only where the
        filter reads a visible frame: on infrared alone the first filter's peak leans to
        smaller sizes (a warm blob that fills more of the window matches better), so a
        tracked horse shrank to 0.8 of its size; nor near another target (its peak at a
        larger size could hold the neighbour).
    anchor_step : float
        The sizes the check compares: the estimated one and this factor above and below it;
        the size moves by it when one side wins, in (1, 1.5]; default 1.05.
    anchor_margin : float
        A side wins when its peak exceeds the estimated size's by this share (and the other
        side's), >= 0; default 0.02. Raising it moves the size less often, on a clearer
        preference.
    window_reuse_px : float
        The translation filter learns from the window its detection took this frame, shifted in
        the Fourier domain so that the learned box's centre lands on the window's centre (ECO's
        sample shift), when that centre lies within this many px of the detection window's and
        the window's size differs by at most this many px at its edge, >= 0; default 1; 0 takes
        the window again at the learned box. It saves the second window of features on about
        two learning frames in three (about 5 % of the tracker's time); the sample it learns has
        its cosine window off the target's centre by up to that distance, and the detection's
        cell grid and size (up to that distance off at the window's edge).
    """

    section = "appearance"

    cell_px: int = param(4, ge=2, le=8)
    padding: float = param(1.5, ge=0.5, le=4)
    template_cells: int = param(24, ge=8, le=64)
    lambda_reg: float = param(1e-2, gt=0)
    label_sigma_factor: float = param(0.1, gt=0, le=1)
    learning_rate: float = param(0.02, ge=0, le=1)
    hog_bins: int = param(9, ge=4, le=18)
    hog_clip: float = param(0.2, gt=0, le=1)
    colour: bool = True
    colour_weight: float = param(3.0, ge=0)
    balance_groups: bool = True
    intensity_clip: float = param(2.5, ge=0)
    visible_gradients: bool = True
    infrared: bool = True
    scale_filter: bool = True
    scale_channels: str = param("adaptive", choices=("infrared", "visible", "both", "adaptive"))
    scale_switch_ratio: float = param(2.0, gt=1)
    scale_count: int = param(13, ge=3, le=33, odd=True)
    scale_step: float = param(1.03, gt=1, le=1.2)
    scale_template_px: int = param(32, ge=16, le=64)
    scale_learning_rate: float = param(0.025, ge=0, le=1)
    max_scale_change: float = param(1.1, gt=1)
    update_every_frames: int = param(1, ge=1)
    scale_every_frames: int = param(1, ge=1)
    scale_reuse_px: float = param(1.0, ge=0)
    anchor_every_frames: int = param(5, ge=0)
    anchor_step: float = param(1.05, gt=1, le=1.5)
    anchor_margin: float = param(0.02, ge=0)
    window_reuse_px: float = param(1.0, ge=0)


# ---------------------------------------------------------------------------------------- features


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _row_gradients(
    g: np.ndarray, y: int, W: int, bins: int, mag: np.ndarray, pos: np.ndarray
) -> None:  # pragma: no cover (compiled)
    """Row ``y`` of a float32 image: gradient magnitude and orientation bin position (unsigned
    orientation in [0, pi) by a polynomial atan, error under 0.002 rad against a bin's 0.35, times
    ``bins / pi``, minus 0.5) of every pixel but the first and last. Branch-free, so that it
    runs in vector registers (``error_model="numpy"``: no zero test before the division, which
    guards itself)."""
    for x in range(1, W - 1):
        gx = g[y, x + 1] - g[y, x - 1]
        gy = g[y + 1, x] - g[y - 1, x]
        mag[x] = np.sqrt(gx * gx + gy * gy)
        ax, ay = abs(gx), abs(gy)
        mx, mn = max(ax, ay), min(ax, ay)
        a = mn / mx if mx > 0.0 else 0.0
        s = a * a
        r = ((-0.0464964749 * s + 0.15931422) * s - 0.327622764) * s * a + a
        r = 1.5707963267948966 - r if ay > ax else r
        # second or fourth quadrant: the unsigned angle is pi - r
        r = 3.141592653589793 - r if (gx < 0.0) != (gy < 0.0) else r
        r = r if r < 3.141592653589793 else 0.0
        pos[x] = r * (bins / 3.141592653589793) - 0.5


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _hog_cells(
    grey: np.ndarray, cell: int, bins: int, clip: float
) -> np.ndarray:  # pragma: no cover (compiled)
    """Normalised gradient-orientation histograms per cell of a float32 image (H, W), H and W
    multiples of cell."""
    H, W = grey.shape
    hc, wc = H // cell, W // cell
    flat = np.zeros(hc * wc * bins, np.float32)
    mag = np.zeros(W, np.float32)
    pos = np.zeros(W, np.float64)
    i0 = np.zeros(W, np.int64)
    i1 = np.zeros(W, np.int64)
    w0 = np.zeros(W, np.float64)
    w1 = np.zeros(W, np.float64)
    for y in range(1, H - 1):
        _row_gradients(grey, y, W, bins, mag, pos)
        # the two bins and weights of every pixel of the row, in vector registers
        for x in range(1, W - 1):
            p = pos[x]
            b0 = np.int64(np.floor(p))
            f = p - b0
            b1 = b0 + 1
            i0[x] = b0 + bins if b0 < 0 else b0
            i1[x] = b1 - bins if b1 >= bins else b1
            m = mag[x]
            w0[x] = m * (1.0 - f)
            w1[x] = m * f
        # then added to the cells: neighbouring cells in turn, so that consecutive additions do
        # not wait on each other; each bin still receives its pixels in the same order
        row = (y // cell) * wc * bins
        for dx in range(cell):
            for cx in range(wc):
                x = cx * cell + dx
                if x < 1 or x >= W - 1 or mag[x] <= 0.0:
                    continue
                base = row + cx * bins
                flat[base + i0[x]] += w0[x]
                flat[base + i1[x]] += w1[x]
    hist = flat.reshape((hc, wc, bins))
    energy = np.zeros((hc, wc), np.float32)
    for cy in range(hc):
        for cx in range(wc):
            s = 0.0
            for b in range(bins):
                s += hist[cy, cx, b] * hist[cy, cx, b]
            energy[cy, cx] = s
    out = np.empty((hc, wc, bins), np.float32)
    for cy in range(hc):
        for cx in range(wc):
            s = 0.0
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    yy, xx = cy + dy, cx + dx
                    if 0 <= yy < hc and 0 <= xx < wc:
                        s += energy[yy, xx]
            inv = 1.0 / np.sqrt(s / 9.0 + 1e-6)
            for b in range(bins):
                v = hist[cy, cx, b] * inv
                out[cy, cx, b] = v if v < clip else clip
    return out


def hog(grey: np.ndarray, cfg: AppearanceConfig) -> np.ndarray:
    """``(H/cell, W/cell, hog_bins)`` float32 gradient-orientation features of a float32 image in
    [0, 1]."""
    return _hog_cells(
        np.ascontiguousarray(grey, np.float32), cfg.cell_px, cfg.hog_bins, np.float32(cfg.hog_clip)
    )


def channel_names(cfg: AppearanceConfig, visible: bool, infrared: bool) -> tuple[str, ...]:
    """The feature channels :func:`features` gives for the channels a sequence has."""
    names: list[str] = []
    if visible:
        if cfg.visible_gradients:
            names += [f"vis-hog{i}" for i in range(cfg.hog_bins)]
        if cfg.colour:
            names += ["vis-L", "vis-a", "vis-b"]
    if infrared and cfg.infrared:
        names += [f"ir-hog{i}" for i in range(cfg.hog_bins)] + ["ir-I"]
    return tuple(names)


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _cell_means(
    img: np.ndarray, ch: int, cell: int, scale: float, offset: float, out: np.ndarray, oc: int
) -> None:  # pragma: no cover (compiled)
    """``out[..., oc]`` = per-cell mean of channel ``ch`` of ``img`` (H, W, K) times ``scale``
    minus ``offset``."""
    hc, wc = out.shape[0], out.shape[1]
    inv = 1.0 / (cell * cell)
    for cy in range(hc):
        for cx in range(wc):
            acc = 0.0
            for y in range(cy * cell, cy * cell + cell):
                for x in range(cx * cell, cx * cell + cell):
                    acc += img[y, x, ch]
            out[cy, cx, oc] = np.float32(acc * inv * scale - offset)


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _window_features(
    lab: np.ndarray,
    ir: np.ndarray,
    cell: int,
    bins: int,
    clip: np.float32,
    colour_weight: float,
    vis_gradients: bool,
    colour: bool,
    infrared: bool,
) -> np.ndarray:  # pragma: no cover (compiled)
    """The channels of :func:`features` in one pass: ``lab`` (H, W, 3) uint8 CIELAB or an empty
    array, ``ir`` (H, W, 1) uint8 or an empty array."""
    use_vis = lab.shape[0] > 0
    use_ir = ir.shape[0] > 0 and infrared
    H, W = (lab.shape[0], lab.shape[1]) if use_vis else (ir.shape[0], ir.shape[1])
    hc, wc = H // cell, W // cell
    C = 0
    if use_vis:
        C += bins * vis_gradients + 3 * colour
    if use_ir:
        C += bins + 1
    out = np.empty((hc, wc, C), np.float32)
    k = 0
    s255 = np.float32(1.0 / 255.0)
    if use_vis:
        if vis_gradients:
            out[:, :, k : k + bins] = _hog_cells(
                lab[:, :, 0].astype(np.float32) * s255, cell, bins, clip
            )
            k += bins
        if colour:
            _cell_means(lab, 0, cell, 1.0 / 255.0, 0.5, out, k)
            _cell_means(lab, 1, cell, colour_weight / 255.0, 0.5 * colour_weight, out, k + 1)
            _cell_means(lab, 2, cell, colour_weight / 255.0, 0.5 * colour_weight, out, k + 2)
            k += 3
    if use_ir:
        grey = ir[:, :, 0].astype(np.float32) * s255
        out[:, :, k : k + bins] = _hog_cells(grey, cell, bins, clip)
        k += bins
        _cell_means(ir, 0, cell, 1.0 / 255.0, 0.0, out, k)
        m = 0.0
        for cy in range(hc):
            for cx in range(wc):
                m += out[cy, cx, k]
        m /= hc * wc
        for cy in range(hc):
            for cx in range(wc):
                out[cy, cx, k] -= np.float32(m)
    return out


_NO_LAB = np.zeros((0, 0, 3), np.uint8)
_NO_IR = np.zeros((0, 0, 1), np.uint8)


def features(vis: np.ndarray | None, ir: np.ndarray | None, cfg: AppearanceConfig) -> np.ndarray:
    """Per-cell features ``(Hc, Wc, C)`` float32 of patches already resized to a multiple of
    ``cell_px``.

    ``vis`` is ``(H, W, 3)`` uint8 BGR or None, ``ir`` ``(H, W)`` uint8 or None; the
    channels are those of :func:`channel_names`, in that order.
    """
    has_vis = vis is not None and (cfg.visible_gradients or cfg.colour)
    if not has_vis and (ir is None or not cfg.infrared):
        raise ValueError("features need at least one channel")
    lab = cv2.cvtColor(vis, cv2.COLOR_BGR2LAB) if vis is not None else _NO_LAB
    return _window_features(
        lab,
        ir[:, :, None] if ir is not None else _NO_IR,
        cfg.cell_px,
        cfg.hog_bins,
        np.float32(cfg.hog_clip),
        float(cfg.colour_weight),
        cfg.visible_gradients,
        cfg.colour,
        cfg.infrared,
    )


# ---------------------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class Window:
    """The search window in frame px and the template size it is resized to (px, multiples of the
    cell)."""

    box: BBox
    template: tuple[int, int]  # (width, height) px

    @property
    def frame_px(self) -> tuple[float, float]:
        """Frame px per template px along x and y."""
        return (self.box.w / self.template[0], self.box.h / self.template[1])


def search_window(
    center: tuple[float, float], size: tuple[float, float], cfg: AppearanceConfig
) -> Window:
    """The window of side ``size * (1 + padding)`` centred on ``center`` and its template size."""
    w, h = size[0] * (1 + cfg.padding), size[1] * (1 + cfg.padding)
    longer = max(w, h)
    cells_w = max(round(cfg.template_cells * w / longer), 4)
    cells_h = max(round(cfg.template_cells * h / longer), 4)
    return Window(
        BBox.from_center(center[0], center[1], w, h),
        (cells_w * cfg.cell_px, cells_h * cfg.cell_px),
    )


def crop(image: np.ndarray, box: BBox, out_size: tuple[int, int]) -> np.ndarray:
    """``box`` (frame px, may extend past the border: replicated) resampled to ``out_size`` (w,
    h)."""
    sx, sy = box.w / out_size[0], box.h / out_size[1]
    M = np.array(
        [[sx, 0.0, box.x + 0.5 * sx - 0.5], [0.0, sy, box.y + 0.5 * sy - 0.5]], np.float64
    )
    interp = cv2.INTER_AREA if min(sx, sy) > 1.5 else cv2.INTER_LINEAR
    if interp == cv2.INTER_AREA:  # downscale: crop with a margin, then area-resize (no aliasing)
        H, W = image.shape[:2]
        x0, y0 = int(np.floor(box.x)), int(np.floor(box.y))
        x1, y1 = int(np.ceil(box.x2)), int(np.ceil(box.y2))
        pad = [max(-y0, 0), max(y1 - H, 0), max(-x0, 0), max(x1 - W, 0)]
        sub = image[max(y0, 0) : min(y1, H), max(x0, 0) : min(x1, W)]
        if sub.size == 0:
            return np.zeros((out_size[1], out_size[0], *image.shape[2:]), image.dtype)
        if any(pad):
            sub = cv2.copyMakeBorder(sub, *pad, cv2.BORDER_REPLICATE)
        return cv2.resize(sub, out_size, interpolation=cv2.INTER_AREA)
    return cv2.warpAffine(
        image,
        M,
        out_size,
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REPLICATE,
    )


@cache
def _hann(h: int, w: int) -> np.ndarray:
    return (np.outer(np.hanning(h + 2)[1:-1], np.hanning(w + 2)[1:-1])).astype(np.float32)[
        ..., None
    ]


@cache
def _label_fft(h: int, w: int, sigma_y: float, sigma_x: float) -> np.ndarray:
    """Spectrum of a Gaussian peaked at cell (h//2, w//2) (rfft2 layout)."""
    yy = np.arange(h, dtype=np.float64) - h // 2
    xx = np.arange(w, dtype=np.float64) - w // 2
    g = np.exp(-0.5 * ((yy[:, None] / sigma_y) ** 2 + (xx[None, :] / sigma_x) ** 2))
    return np.fft.rfft2(g)


# --------------------------------------------------------------------------------------- the model


@dataclass(frozen=True)
class AppearanceModel:
    """A learned filter pair: translation (``num``, ``den``) and scale (``s_num``, ``s_den``), and
    the target size they were learned at (frame px)."""

    num: np.ndarray  # (Hc, Wc//2+1, C) complex
    den: np.ndarray  # (Hc, Wc//2+1) real
    template: tuple[int, int]  # (w, h) px of the translation template
    size: tuple[float, float]  # target (w, h) frame px
    s_num: np.ndarray  # (d, S//2+1) complex
    s_den: np.ndarray  # (S//2+1,) real
    channels: tuple[bool, bool]  # (visible, infrared) the features were built from
    scale_template: tuple[int, int]  # (w, h) px of the scale filter's template
    gains: np.ndarray  # (C,) per-channel feature gains fixed at the first frame
    frames: int = 1
    scale_source: str = "infrared"  # the frame(s) the scale filter reads where both exist
    support_log_ratio: float = 0.0  # running mean of log(visible PSR / IR PSR), ``adaptive``


@dataclass(frozen=True)
class Detection:
    """Where the filter finds the target: centre (frame px), its peak and PSR, and the scale
    filter's size."""

    center: tuple[float, float]
    peak: float
    psr: float
    size: tuple[float, float]
    scale_factor: float
    support: tuple[float, float] = (
        float("nan"),
        float("nan"),
    )  # (visible, IR): each channel's PSR at the peak
    response: np.ndarray | None = None
    scale_samples: ScaleSamples | None = None
    window_samples: WindowSamples | None = None


@dataclass(frozen=True)
class WindowSamples:
    """The translation filter's sample of one frame, as :func:`detect` took it: the spectra
    ``(Hc, Wc // 2 + 1, C)`` of the weighted, windowed features of the search window ``box``
    (frame px) on ``template``."""

    box: BBox
    template: tuple[int, int]
    spectra: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class ScaleSamples:
    """The scale filter's samples of one frame, as :func:`rescale` took them: ``features``
    ``(d, scale_count)`` windowed over the scales, around ``center`` (frame px) at ``size``
    times each scale's factor, on ``template``."""

    center: tuple[float, float]
    size: tuple[float, float]
    template: tuple[int, int]
    features: np.ndarray = field(repr=False)


def _patches(
    vis: np.ndarray | None, ir: np.ndarray | None, box: BBox, size: tuple[int, int]
) -> tuple[np.ndarray | None, np.ndarray | None]:
    return (
        crop(vis, box, size) if vis is not None else None,
        crop(ir, box, size) if ir is not None else None,
    )


@cache
def channel_groups(cfg: AppearanceConfig, visible: bool, infrared: bool) -> np.ndarray:
    """Group index per feature channel: visible gradients, visible colour, IR gradients, IR
    intensity."""
    names = channel_names(cfg, visible, infrared)
    kind = {"vis-hog": 0, "vis-L": 1, "vis-a": 1, "vis-b": 1, "ir-hog": 2, "ir-I": 3}
    groups = np.array([kind[n.rstrip("0123456789")] for n in names])
    groups.flags.writeable = False  # shared by every call (cached)
    return groups


@cache
def _clipped(cfg: AppearanceConfig, visible: bool, infrared: bool) -> np.ndarray:
    """Per channel: clipped at ``intensity_clip`` (the colour and IR intensity channels)."""
    groups = channel_groups(cfg, visible, infrared)
    out = ((groups == 1) | (groups == 3)) & (cfg.balance_groups and cfg.intensity_clip > 0)
    out.flags.writeable = False
    return out


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _weigh(
    f: np.ndarray, gains: np.ndarray, clipped: np.ndarray, limit: float, hann: np.ndarray
) -> np.ndarray:  # pragma: no cover (compiled)
    """``f * gains``, the ``clipped`` channels clipped to +-``limit``, times the window."""
    h, w, C = f.shape
    out = np.empty((h, w, C), np.float32)
    lim = np.float32(limit)
    for y in range(h):
        for x in range(w):
            win = hann[y, x, 0]
            for c in range(C):
                v = f[y, x, c] * gains[c]
                if clipped[c]:
                    v = min(max(v, -lim), lim)
                out[y, x, c] = v * win
    return out


def group_gains(f: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Per-channel gains that give every feature group the same energy per cell in ``f`` (the first
    frame's window): a group's gain is ``1 / rms`` of its channels, so that the IR's heat counts as
    much as the visible gradients whatever the contrast of either."""
    gains = np.ones(f.shape[2], np.float32)
    for g in np.unique(groups):
        sel = groups == g
        rms = float(np.sqrt(np.mean(np.sum(f[..., sel] ** 2, axis=2))))
        gains[sel] = 1.0 / rms if rms > 1e-6 else 0.0
    return gains


def _rfft2(x: np.ndarray) -> np.ndarray:
    """``scipy.fft.rfft2(x, axes=(0, 1))`` of a real array, bit for bit."""
    if _pocketfft is None:  # pragma: no cover
        return fft.rfft2(x, axes=(0, 1))
    return _pocketfft.r2c(x, (0, 1), True, 0, None, 1)


def _irfft2(X: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``scipy.fft.irfft2(X, s=shape, axes=(0, 1))`` of a complex spectrum of that shape, bit for
    bit."""
    if _pocketfft is None or X.shape[:2] != (shape[0], shape[1] // 2 + 1):  # pragma: no cover
        return fft.irfft2(X, s=shape, axes=(0, 1))
    return _pocketfft.c2r(X, (0, 1), shape[1], False, 2, None, 1)


def _rfft_rows(x: np.ndarray) -> np.ndarray:
    """``scipy.fft.rfft(x, axis=1)`` of a real 2-D array, bit for bit."""
    if _pocketfft is None:  # pragma: no cover
        return fft.rfft(x, axis=1)
    return _pocketfft.r2c(x, (1,), True, 0, None, 1)


def _irfft(X: np.ndarray, n: int) -> np.ndarray:
    """``scipy.fft.irfft(X, n=n)`` of a complex 1-D spectrum of ``n // 2 + 1`` values, bit for
    bit."""
    if _pocketfft is None or X.shape != (n // 2 + 1,) or not np.iscomplexobj(X):
        return fft.irfft(X, n=n)  # pragma: no cover
    return _pocketfft.c2r(X, (0,), n, False, 2, None, 1)


def _translation_spectra(
    vis, ir, win: Window, cfg: AppearanceConfig, gains: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The windowed features' spectra and the gains applied (``gains`` None: computed from these
    features)."""
    v, i = _patches(vis, ir, win.box, win.template)
    f = features(v, i, cfg)
    if gains is None:
        groups = channel_groups(cfg, vis is not None, ir is not None)
        gains = group_gains(f, groups) if cfg.balance_groups else np.ones(f.shape[2], np.float32)
    # a far hotter (or brighter) neighbour entering the window must not outweigh the target by
    # its energy: the intensity channels are clipped
    g = _weigh(
        f,
        gains,
        _clipped(cfg, vis is not None, ir is not None),
        cfg.intensity_clip,
        _hann(f.shape[0], f.shape[1]),
    )
    return _rfft2(g), gains


@cache
def _scale_factors(count: int, step: float) -> np.ndarray:
    return step ** (np.arange(count) - count // 2)


@cache
def _scale_window(count: int) -> np.ndarray:
    return np.hanning(count + 2)[1:-1].astype(np.float32)


@cache
def _scale_label_fft(count: int) -> np.ndarray:
    """Spectrum of the scale label: a Gaussian over the scales, width sqrt(S) / 4 (DSST), peaked at
    index 0."""
    n = np.arange(count, dtype=np.float64) - count // 2
    g = np.exp(-0.5 * (n / max(np.sqrt(count) / 4.0, 0.5)) ** 2)
    return np.fft.rfft(np.fft.ifftshift(g))


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _scale_hog(
    img: np.ndarray,
    ox: float,
    oy: float,
    cx: float,
    cy: float,
    w: float,
    h: float,
    factors: np.ndarray,
    tw: int,
    th: int,
    cell: int,
    bins: int,
    clip: float,
    window: np.ndarray,
) -> np.ndarray:  # pragma: no cover (compiled)
    """Gradient features of the target at every scale: (d, S), each column the HOG of a ``th x tw``
    template sampled bilinearly (from the smoothed region ``img`` whose corner is frame px (ox,
    oy)) over the box of size (w, h) * factor centred on (cx, cy), times ``window[k]``
    (float32)."""
    H, W = img.shape
    S = factors.shape[0]
    d = (th // cell) * (tw // cell) * bins
    out = np.empty((d, S), np.float32)
    tpl = np.empty((th, tw), np.float32)
    ixs = np.empty(tw, np.int64)
    axs = np.empty(tw, np.float64)
    for k in range(S):
        bw, bh = w * factors[k], h * factors[k]
        sx, sy = bw / tw, bh / th
        x0, y0 = cx - 0.5 * bw - ox, cy - 0.5 * bh - oy
        for c in range(tw):  # the columns' sample positions, the same on every row
            fx = x0 + (c + 0.5) * sx - 0.5
            fx = min(max(fx, 0.0), W - 1.0)
            ix = min(int(fx), W - 2) if W > 1 else 0
            ixs[c] = ix
            axs[c] = fx - ix
        for r in range(th):
            fy = y0 + (r + 0.5) * sy - 0.5
            fy = min(max(fy, 0.0), H - 1.0)
            iy = min(int(fy), H - 2) if H > 1 else 0
            ay = fy - iy
            for c in range(tw):
                ix = ixs[c]
                ax = axs[c]
                top = img[iy, ix] * (1 - ax) + img[iy, ix + 1] * ax
                bot = img[iy + 1, ix] * (1 - ax) + img[iy + 1, ix + 1] * ax
                tpl[r, c] = top * (1 - ay) + bot * ay
        f = _hog_cells(tpl, cell, bins, clip).ravel()
        wk = window[k]
        for i in range(d):
            out[i, k] = f[i] * wk
    return out


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _unit_region(src, y0, y1, x0, x1, s):  # pragma: no cover (compiled)
    """``src[y0:y1, x0:x1]`` (uint8) as float32 times ``s`` (float32), as numpy's
    ``astype(np.float32) * s``."""
    out = np.empty((y1 - y0, x1 - x0), np.float32)
    for i in range(y0, y1):
        for j in range(x0, x1):
            out[i - y0, j - x0] = np.float32(src[i, j]) * s
    return out


def scale_template(size: tuple[float, float], cfg: AppearanceConfig) -> tuple[int, int]:
    """(w, h) px of the scale filter's template for a target of ``size``: about
    ``scale_template_px`` square, the target's aspect, whole cells."""
    t = cfg.scale_template_px
    aspect = size[0] / max(size[1], 1e-6)
    tw = max(round(t * np.sqrt(aspect) / cfg.cell_px), 2) * cfg.cell_px
    th = max(round(t / np.sqrt(aspect) / cfg.cell_px), 2) * cfg.cell_px
    return tw, th


def _scale_samples(
    vis,
    ir,
    center: tuple[float, float],
    size: tuple[float, float],
    cfg: AppearanceConfig,
    template: tuple[int, int],
    source: str = "infrared",
) -> np.ndarray:
    """``(d, S)`` features of the target at every scale, windowed over the scales: the gradient
    histogram of the ``source`` frame (``infrared``, ``visible`` or ``both``; the one there is
    where the other is missing) on a ``template`` (w, h) px resampling, one compiled pass over all
    scales."""
    tw, th = template
    factors = _scale_factors(cfg.scale_count, cfg.scale_step)
    sources = []
    if vis is not None and (ir is None or source in ("visible", "both")):
        sources.append(cv2.cvtColor(vis, cv2.COLOR_BGR2GRAY))
    if ir is not None and (vis is None or source in ("infrared", "both")):
        sources.append(ir)
    big = (size[0] * factors[-1], size[1] * factors[-1])
    Hf, Wf = sources[0].shape[:2]
    x0, y0 = max(int(center[0] - 0.5 * big[0]) - 2, 0), max(int(center[1] - 0.5 * big[1]) - 2, 0)
    x1, y1 = min(int(center[0] + 0.5 * big[0]) + 3, Wf), min(int(center[1] + 0.5 * big[1]) + 3, Hf)
    d = (th // cfg.cell_px) * (tw // cfg.cell_px) * cfg.hog_bins
    if x1 - x0 < 2 or y1 - y0 < 2:
        return np.zeros((d * len(sources), cfg.scale_count), np.float32)
    parts = []
    window = _scale_window(cfg.scale_count)
    for src in sources:
        region = _unit_region(src, y0, y1, x0, x1, np.float32(1.0 / 255.0))
        down = size[1] / th  # anti-alias before sampling down
        if down > 1.5:
            region = cv2.GaussianBlur(region, (0, 0), 0.5 * down)
        parts.append(
            _scale_hog(
                region,
                float(x0),
                float(y0),
                float(center[0]),
                float(center[1]),
                float(size[0]),
                float(size[1]),
                factors,
                tw,
                th,
                cfg.cell_px,
                cfg.hog_bins,
                np.float32(cfg.hog_clip),
                window,
            )
        )
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=0)


def _check_channels(vis_used: bool, ir_used: bool, channels: tuple[bool, bool]) -> None:
    if channels != (vis_used, ir_used):
        raise ValueError(
            f"the model was built from channels {channels}, the frame gives {(vis_used, ir_used)}"
        )


def reused_scale_samples(
    reuse: ScaleSamples, box: BBox, template: tuple[int, int], cfg: AppearanceConfig
) -> np.ndarray | None:
    """The scale samples of ``box`` made from ``reuse`` (a detection's of the same frame), or None
    where they cannot be: ``box``'s centre farther than ``cfg.scale_reuse_px`` from theirs,
    another template or aspect (1 %), or a size more than one scale step away. Scale ``k`` of
    ``box`` lies ``delta = log(box.w / reuse.size[0]) / log(scale_step)`` steps along the
    detection's scales: each sample is the detection's two neighbouring ones blended linearly
    (unwindowed, then windowed again; the end scales held beyond the ends).

    Examples
    --------
    >>> cfg = AppearanceConfig(scale_count=3, scale_reuse_px=1.0)
    >>> w = _scale_window(3)
    >>> r = ScaleSamples((10.0, 10.0), (10.0, 20.0), (8, 16), np.array([[1.0, 2.0, 4.0]]) * w)
    >>> half = BBox.from_center(10.5, 10.0, 10.0 * 1.03**0.5, 20.0 * 1.03**0.5)
    >>> np.round(reused_scale_samples(r, half, (8, 16), cfg) / w, 6)
    array([[1.5, 3. , 4. ]], dtype=float32)
    >>> reused_scale_samples(r, BBox.from_center(12.0, 10.0, 10.0, 20.0), (8, 16), cfg) is None
    True
    """
    if (
        template != reuse.template
        or math.hypot(box.cx - reuse.center[0], box.cy - reuse.center[1]) > cfg.scale_reuse_px
        or abs((box.w / box.h) / (reuse.size[0] / reuse.size[1]) - 1.0) > 0.01
    ):
        return None
    delta = math.log(box.w / reuse.size[0]) / math.log(cfg.scale_step)
    if abs(delta) > 1.0:
        return None
    return _moved_scales(reuse.features, _scale_window(cfg.scale_count), delta)


@numba.njit(cache=True, boundscheck=False, nogil=True)
def _moved_scales(f, window, delta):  # pragma: no cover (compiled)
    """``f`` (d, S) moved ``delta`` scales along: column ``k`` blends columns ``j`` and ``j + 1``
    around ``k + delta`` (held at the ends), each divided by its ``window`` value, then times
    ``window[k]`` (float32)."""
    d, n = f.shape
    lo = np.empty(n, np.intp)
    t = np.empty(n, np.float32)
    for k in range(n):
        p = min(max(k + delta, 0.0), n - 1.0)
        lo[k] = min(int(np.floor(p)), n - 2)
        t[k] = np.float32(p - lo[k])
    out = np.empty((d, n), np.float32)
    raw = np.empty(n, np.float32)
    one = np.float32(1.0)
    for i in range(d):
        for k in range(n):
            raw[k] = f[i, k] / window[k]
        for k in range(n):
            j = lo[k]
            out[i, k] = (raw[j] * (one - t[k]) + raw[j + 1] * t[k]) * window[k]
    return out


def train(
    vis: np.ndarray | None,
    ir: np.ndarray | None,
    box: BBox,
    cfg: AppearanceConfig,
    like: AppearanceModel | None = None,
    scale: bool = True,
    reuse: ScaleSamples | None = None,
    reuse_window: WindowSamples | None = None,
) -> AppearanceModel:
    """A new model of the target in ``box`` (frame px) of the frames (either may be None); with
    ``like``, on that model's templates (so the two can be blended whatever the box's aspect);
    ``scale`` False leaves the scale filter out (zeros). ``reuse`` and ``reuse_window``: this
    frame's detection samples, learned from instead of new ones where ``cfg.scale_reuse_px`` and
    ``cfg.window_reuse_px`` allow (:func:`reused_scale_samples`, :func:`reused_window`)."""
    win = search_window(box.center, (box.w, box.h), cfg)
    if like is not None:
        win = Window(win.box, like.template)
    F = None
    if like is not None and reuse_window is not None:
        F = reused_window(reuse_window, win, cfg)
        if F is not None and F.shape[2] != like.num.shape[2]:
            F = None
    if F is None:
        F, gains = _translation_spectra(
            vis, ir, win, cfg, like.gains if like is not None else None
        )
    else:
        gains = like.gains  # type: ignore[union-attr]
    Y = _label_fft(
        win.template[1] // cfg.cell_px, win.template[0] // cfg.cell_px, *_sigmas(box, win, cfg)
    )
    num, den = _filter_terms(Y, F)
    st = like.scale_template if like is not None else scale_template((box.w, box.h), cfg)
    source = like.scale_source if like is not None else _first_scale_source(cfg)
    if cfg.scale_filter and scale:
        S = reused_scale_samples(reuse, box, st, cfg) if reuse is not None else None
        if S is None:
            S = _scale_samples(vis, ir, box.center, (box.w, box.h), cfg, st, source)
        s_num, s_den = _scale_terms(_scale_label_fft(cfg.scale_count), _rfft_rows(S))
    else:
        s_num, s_den = (
            np.zeros((1, cfg.scale_count // 2 + 1), complex),
            np.zeros(cfg.scale_count // 2 + 1),
        )
    return AppearanceModel(
        num,
        den,
        win.template,
        (box.w, box.h),
        s_num,
        s_den,
        (vis is not None, ir is not None),
        st,
        gains,
        scale_source=source,
    )


def reused_window(reuse: WindowSamples, win: Window, cfg: AppearanceConfig) -> np.ndarray | None:
    """The translation spectra of window ``win`` made from ``reuse`` (a detection's of the same
    frame): ``reuse``'s spectra shifted by the windows' offset, or None where they cannot be:
    another template, the windows' centres farther apart than ``cfg.window_reuse_px``, or their
    sizes differing by more than that at the edge.

    The features are shifted as band-limited signals (a fraction of a cell is interpolated between
    cells), so that the target lands on the window's centre, where the filter's label peaks; the
    cosine window stays where the detection put it, and the cells keep the detection's phase.

    Examples
    --------
    >>> cfg = AppearanceConfig(window_reuse_px=2.0)
    >>> f = np.zeros((8, 8, 1), np.float32); f[4, 4] = 1.0
    >>> r = WindowSamples(BBox(0.0, 0.0, 32.0, 32.0), (32, 32), _rfft2(f))
    >>> F = reused_window(r, Window(BBox(-2.0, 0.0, 32.0, 32.0), (32, 32)), cfg)
    >>> g = _irfft2(F, (8, 8))[..., 0]  # the window moved half a cell left: the peak half right
    >>> np.round(g[4, 4:6], 3), int(np.argmax(g[4]))
    (array([0.628, 0.628], dtype=float32), 4)
    >>> reused_window(r, Window(BBox(-3.0, 0.0, 32.0, 32.0), (32, 32)), cfg) is None
    True
    """
    if win.template != reuse.template:
        return None
    dx, dy = win.box.cx - reuse.box.cx, win.box.cy - reuse.box.cy
    edge = 0.5 * max(abs(win.box.w - reuse.box.w), abs(win.box.h - reuse.box.h))
    if math.hypot(dx, dy) > cfg.window_reuse_px or edge > cfg.window_reuse_px:
        return None
    fx, fy = reuse.box.w / reuse.template[0], reuse.box.h / reuse.template[1]
    w = reuse.template[0] // cfg.cell_px  # the features' width: the spectra hold w // 2 + 1
    return _shifted(reuse.spectra, dy / (fy * cfg.cell_px), dx / (fx * cfg.cell_px), w)


@numba.njit(cache=True, boundscheck=False, nogil=True)
def _shifted(F, sy, sx, w):  # pragma: no cover (compiled)
    """The spectra ``F`` (h, w // 2 + 1, C) of features ``f`` (h, w, C; rfft2 over the first two
    axes) of ``g(y, x) = f(y + sy, x + sx)``: each frequency times ``exp(2 pi i (ky sy / h + kx
    sx / w))``, ``ky`` signed."""
    h, wf, C = F.shape
    out = np.empty_like(F)
    for y in range(h):
        ky = y if y <= h // 2 else y - h
        for x in range(wf):
            ph = 2.0 * np.pi * (ky * sy / h + x * sx / w)
            e = complex(np.cos(ph), np.sin(ph))
            for c in range(C):
                out[y, x, c] = F[y, x, c] * e
    return out


@numba.njit(cache=True, boundscheck=False, nogil=True)
def _filter_terms(label, F):  # pragma: no cover (compiled)
    """The translation filter's numerator ``conj(label) * F`` per channel (complex128) and
    denominator ``sum_c |F_c|^2`` (float32) of the spectra ``F`` (h, wf, C) complex64 and the
    label's spectrum (h, wf)."""
    h, wf, C = F.shape
    num = np.empty((h, wf, C), np.complex128)
    den = np.empty((h, wf), np.float32)
    for y in range(h):
        for x in range(wf):
            cl = np.conj(label[y, x])
            s = np.float32(0.0)
            for c in range(C):
                f = F[y, x, c]
                num[y, x, c] = cl * np.complex128(f)
                s += f.real * f.real + f.imag * f.imag
            den[y, x] = s
    return num, den


@numba.njit(cache=True, boundscheck=False, nogil=True)
def _scale_terms(label, Fs):  # pragma: no cover (compiled)
    """The scale filter's numerator ``conj(label) * Fs`` (complex128) and denominator ``sum_i
    |Fs_i|^2`` over the features (float32) of the spectra ``Fs`` (d, n) complex64 and the label's
    spectrum (n,)."""
    d, n = Fs.shape
    num = np.empty((d, n), np.complex128)
    den = np.zeros(n, np.float32)
    for i in range(d):
        for k in range(n):
            f = Fs[i, k]
            num[i, k] = np.conj(label[k]) * np.complex128(f)
            den[k] += f.real * f.real + f.imag * f.imag
    return num, den


@numba.njit(cache=True, boundscheck=False, nogil=True)
def _scale_response(s_num, Fs, s_den, lam):  # pragma: no cover (compiled)
    """The scale filter's response spectrum ``sum_i conj(s_num_i) Fs_i / (s_den + lam)`` over
    the features ``i`` of ``Fs`` (d, n); ``lam`` of ``s_den``'s type, as numpy adds it."""
    d, n = Fs.shape
    acc = np.zeros(n, np.complex128)
    for i in range(d):
        for k in range(n):
            acc[k] += np.conj(s_num[i, k]) * np.complex128(Fs[i, k])
    out = np.empty(n, np.complex128)
    for k in range(n):
        den = s_den[k] + lam
        out[k] = complex(acc[k].real / den, acc[k].imag / den)
    return out


def _sigmas(box: BBox, win: Window, cfg: AppearanceConfig) -> tuple[float, float]:
    """The label's width in cells: ``label_sigma_factor`` of the target's size in cells (KCF,
    DSST)."""
    fx, fy = win.frame_px
    tw, th = box.w / (fx * cfg.cell_px), box.h / (fy * cfg.cell_px)
    s = cfg.label_sigma_factor * np.sqrt(max(tw * th, 1.0))
    return (max(s, 0.5), max(s, 0.5))


@numba.njit(cache=True, inline="always", error_model="numpy", nogil=True)
def _refine(a: float, b: float, c: float) -> float:  # pragma: no cover (compiled)
    """Sub-cell offset of a peak ``b`` between ``a`` and ``c`` (a parabola), in [-0.5, 0.5]."""
    d = a - 2 * b + c
    return 0.0 if d >= 0 else min(max(0.5 * (a - c) / d, -0.5), 0.5)


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _peak(r: np.ndarray) -> tuple[float, float, float, int, int]:  # pragma: no cover (compiled)
    """Peak of a response map (the first maximum): (dy, dx) sub-cell displacement from the
    centre cell, value, and its cell."""
    h, w = r.shape
    iy, ix = 0, 0
    best = r[0, 0]
    for y in range(h):
        for x in range(w):
            if r[y, x] > best:
                best, iy, ix = r[y, x], y, x
    dy = _refine(r[(iy - 1) % h, ix], best, r[(iy + 1) % h, ix])
    dx = _refine(r[iy, (ix - 1) % w], best, r[iy, (ix + 1) % w])
    return float(iy + dy - h // 2), float(ix + dx - w // 2), float(best), iy, ix


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _psr(r: np.ndarray, iy: int, ix: int, exclude: int) -> float:  # pragma: no cover (compiled)
    h, w = r.shape
    n, total = 0, 0.0
    for y in range(h):
        near_y = (y - iy + exclude) % h <= 2 * exclude
        for x in range(w):
            if near_y and (x - ix + exclude) % w <= 2 * exclude:
                continue
            total += r[y, x]
            n += 1
    if n == 0:
        return 0.0
    mean = total / n
    var = 0.0
    for y in range(h):
        near_y = (y - iy + exclude) % h <= 2 * exclude
        for x in range(w):
            if near_y and (x - ix + exclude) % w <= 2 * exclude:
                continue
            var += (r[y, x] - mean) ** 2
    sd = np.sqrt(var / n)
    return (r[iy, ix] - mean) / sd if sd > 1e-12 else 0.0


def _peak_offset(r: np.ndarray) -> tuple[float, float, float, int, int]:
    """Peak of a response map: (dy, dx) sub-cell displacement from the centre cell, value, and its
    cell."""
    return _peak(np.ascontiguousarray(r, np.float64))


def psr(r: np.ndarray, iy: int, ix: int, exclude: int = 2) -> float:
    """Peak-to-sidelobe ratio: (peak - mean) / std of the response outside the ``2 * exclude + 1``
    cells around it."""
    return float(_psr(np.ascontiguousarray(r, np.float64), iy, ix, exclude))


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _correlate(
    Z: np.ndarray, num: np.ndarray, inv: np.ndarray, split: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover (compiled)
    """``sum_l conj(A_l) Z_l / (B + lambda)`` over the channels before ``split`` and over those
    after it (the visible and the infrared parts of the response's spectrum)."""
    h, wf, C = Z.shape
    a = np.empty((h, wf), np.complex128)
    b = np.empty((h, wf), np.complex128)
    for y in range(h):
        for x in range(wf):
            sa = 0j
            sb = 0j
            for c in range(split):
                sa += np.conj(num[y, x, c]) * Z[y, x, c]
            for c in range(split, C):
                sb += np.conj(num[y, x, c]) * Z[y, x, c]
            a[y, x] = sa * inv[y, x]
            b[y, x] = sb * inv[y, x]
    return a, b


@cache
def _visible_channels(cfg: AppearanceConfig) -> int:
    return len(channel_names(cfg, True, False))


def detect(
    model: AppearanceModel,
    vis: np.ndarray | None,
    ir: np.ndarray | None,
    center: tuple[float, float],
    cfg: AppearanceConfig,
    size: tuple[float, float] | None = None,
    with_scale: bool = True,
    keep_response: bool = False,
) -> Detection:
    """Find the target around ``center`` (frame px) with the model's filters.

    ``size`` is the target size to search with (default the model's); the window keeps the
    model's template shape, so the filter applies at any size. ``with_scale`` False leaves the
    size as it is (:func:`rescale` adds the scale filter's estimate later).
    """
    _check_channels(vis is not None, ir is not None, model.channels)
    sz = size or model.size
    win = Window(search_window(center, sz, cfg).box, model.template)
    Z, _ = _translation_spectra(vis, ir, win, cfg, model.gains)
    # the label peaks on the centre cell: the response peaks there plus the target's displacement
    inv = 1.0 / (model.den + cfg.lambda_reg)
    shape = (Z.shape[0], model.template[0] // cfg.cell_px)
    both = all(model.channels)
    a, b = _correlate(Z, model.num, inv, _visible_channels(cfg) if both else Z.shape[2])
    resp = resp_v = _irfft2(a, shape)
    if both:  # the two channels' responses apart: how each supports the joint peak
        resp_i = _irfft2(b, shape)
        resp = resp_v + resp_i
    dy, dx, peak, iy, ix = _peak(resp)
    fx, fy = win.frame_px
    cx = center[0] + dx * fx * cfg.cell_px
    cy = center[1] + dy * fy * cfg.cell_px
    q = float(_psr(resp, iy, ix, 2))
    support = (
        (float(_psr(resp_v, iy, ix, 2)), float(_psr(resp_i, iy, ix, 2)))
        if both
        else ((q, float("nan")) if model.channels[0] else (float("nan"), q))
    )
    kept = WindowSamples(win.box, win.template, Z) if cfg.window_reuse_px > 0 else None
    d = Detection(
        (cx, cy),
        peak,
        q,
        sz,
        1.0,
        support,
        resp if keep_response else None,
        window_samples=kept,
    )
    return rescale(model, d, vis, ir, cfg) if with_scale else d


def rescale(
    model: AppearanceModel,
    d: Detection,
    vis: np.ndarray | None,
    ir: np.ndarray | None,
    cfg: AppearanceConfig,
) -> Detection:
    """``d`` with the scale filter's size at its centre (``d.size`` the size searched from);
    ``d`` itself when the scale filter is off."""
    if not cfg.scale_filter:
        return d
    sz = d.size
    S = _scale_samples(vis, ir, d.center, sz, cfg, model.scale_template, model.scale_source)
    rs = _irfft(
        _scale_response(
            model.s_num, _rfft_rows(S), model.s_den, model.s_den.dtype.type(cfg.lambda_reg)
        ),
        cfg.scale_count,
    )
    k, off = _scale_peak(rs)
    f = _scale_factors(cfg.scale_count, cfg.scale_step)
    factor = float(f[k] * cfg.scale_step**off)
    factor = min(max(factor, 1 / cfg.max_scale_change), cfg.max_scale_change)
    kept = ScaleSamples(d.center, sz, model.scale_template, S) if cfg.scale_reuse_px > 0 else None
    return Detection(
        d.center,
        d.peak,
        d.psr,
        (sz[0] * factor, sz[1] * factor),
        factor,
        d.support,
        d.response,
        kept,
        d.window_samples,
    )


def anchor_factor(
    first: AppearanceModel,
    d: Detection,
    vis: np.ndarray | None,
    ir: np.ndarray | None,
    cfg: AppearanceConfig,
) -> float:
    """The factor the target's first filter ``first`` moves ``d.size`` by: ``anchor_step``
    where the translation peak at ``d.size`` times it exceeds the peak at ``d.size`` by
    ``anchor_margin`` (and the peak at ``d.size`` over it), its inverse the other way round,
    else 1. Each peak is the best over the window around ``d.center``.

    The first filter has learned nothing since the first frame, so it peaks at the size the
    target has now, up to its change of shape (within about a tenth on walkers, cyclists and
    cars of the random family); the scale filter that learns each frame does not.

    Examples
    --------
    A textured target trained at 40 x 40 px, searched at 32 x 32 px on the same frame, is
    moved up a step:

    >>> rng = np.random.default_rng(0)
    >>> img = cv2.GaussianBlur(rng.integers(0, 255, (160, 160), dtype=np.uint8), (5, 5), 1)
    >>> cfg = AppearanceConfig()
    >>> m = train(None, img, BBox(60, 60, 40, 40), cfg)
    >>> d = Detection((80.0, 80.0), 1.0, 10.0, (32.0, 32.0), 1.0)
    >>> anchor_factor(m, d, None, img, cfg)
    1.05
    >>> anchor_factor(m, replace(d, size=(40.0, 40.0)), None, img, cfg)
    1.0
    """
    q, m = cfg.anchor_step, cfg.anchor_margin
    w, h = d.size
    below, here, above = (
        detect(first, vis, ir, d.center, cfg, size=(w * s, h * s), with_scale=False).peak
        for s in (1 / q, 1.0, q)
    )
    if above > here * (1 + m) and above >= below:
        return q
    if below > here * (1 + m) and below > above:
        return 1 / q
    return 1.0


@numba.njit(cache=True, boundscheck=False, error_model="numpy", nogil=True)
def _scale_peak(rs):  # pragma: no cover (compiled)
    """The scale response's peak after ``fftshift``: its index and :func:`_refine`'s offset (0 at
    either end)."""
    n = rs.shape[0]
    h = n // 2
    k = 0
    best = rs[(0 - h) % n]
    for j in range(1, n):
        v = rs[(j - h) % n]
        if best != best:  # numpy's argmax: the first NaN wins
            break
        if v > best or v != v:
            best, k = v, j
    if 0 < k < n - 1:
        return k, _refine(rs[(k - 1 - h) % n], best, rs[(k + 1 - h) % n])
    return k, 0.0


def _first_scale_source(cfg: AppearanceConfig) -> str:
    """The frame(s) a new scale filter reads: ``scale_channels``, the infrared for
    ``adaptive``."""
    return "infrared" if cfg.scale_channels == "adaptive" else cfg.scale_channels


def scale_source_after(
    model: AppearanceModel, support: tuple[float, float], cfg: AppearanceConfig
) -> tuple[str, float]:
    """An ``adaptive`` scale filter's frame after a frame whose detection had the (visible, IR)
    PSR ``support``, and the running mean of ``log(visible / IR)`` it is chosen by (each PSR
    floored at 1; a weight of 0.1 per frame, about the last ten learning frames): the visible
    frame from ``log(scale_switch_ratio)`` up, the infrared again from 0 down (the IR shows the
    target as well), else unchanged. A frame without both PSRs changes nothing.

    Examples
    --------
    >>> cfg = AppearanceConfig(scale_channels="adaptive")
    >>> m = AppearanceModel(*(None,) * 4, None, None, (True, True), (8, 8), None)
    >>> for _ in range(10):  # the IR shows the target at a third of the visible's PSR
    ...     src, r = scale_source_after(m, (30.0, 10.0), cfg)
    ...     m = replace(m, scale_source=src, support_log_ratio=r)
    >>> m.scale_source, round(m.support_log_ratio, 3)
    ('visible', 0.716)
    >>> scale_source_after(m, (10.0, 40.0), cfg)[0]  # one frame of a clear IR: not yet
    'visible'
    """
    v, i = support
    if not (math.isfinite(v) and math.isfinite(i)):
        return model.scale_source, model.support_log_ratio
    ratio = 0.9 * model.support_log_ratio + 0.1 * math.log(max(v, 1.0) / max(i, 1.0))
    source = model.scale_source
    if ratio >= math.log(cfg.scale_switch_ratio):
        source = "visible"
    elif ratio <= 0.0:
        source = "infrared"
    return source, ratio


def update(
    model: AppearanceModel,
    vis: np.ndarray | None,
    ir: np.ndarray | None,
    box: BBox,
    cfg: AppearanceConfig,
    rate: float | None = None,
    scale_rate: float | None = None,
    reuse: ScaleSamples | None = None,
    reuse_window: WindowSamples | None = None,
    support: tuple[float, float] | None = None,
) -> AppearanceModel:
    """The model with the target in ``box`` blended in (``rate`` defaults to ``cfg.learning_rate``;
    0 keeps it); ``reuse`` and ``reuse_window`` as :func:`train`'s. ``support``: this frame's
    (visible, IR) PSR at the detection, which moves an ``adaptive`` scale filter
    (:func:`scale_source_after`); where it moves, the scale filter is learned afresh."""
    r = cfg.learning_rate if rate is None else rate
    rs = cfg.scale_learning_rate if scale_rate is None else scale_rate
    if r <= 0 and rs <= 0:
        return model
    moved = False
    if cfg.scale_channels == "adaptive" and support is not None and all(model.channels):
        source, ratio = scale_source_after(model, support, cfg)
        moved = source != model.scale_source
        model = replace(model, scale_source=source, support_log_ratio=ratio)
        if moved:
            reuse, rs = None, 1.0  # the other frame's samples: learned afresh, not blended
    new = train(
        vis, ir, box, cfg, like=model, scale=rs > 0, reuse=reuse, reuse_window=reuse_window
    )
    num, den = model.num, model.den
    if r > 0:
        num, den = blend(model.num, new.num, r), blend(model.den, new.den, r)
    s_num, s_den = model.s_num, model.s_den
    if rs > 0 and cfg.scale_filter:
        s_num, s_den = blend(model.s_num, new.s_num, rs), blend(model.s_den, new.s_den, rs)
    return replace(
        model,
        num=num,
        den=den,
        s_num=s_num,
        s_den=s_den,
        size=(box.w, box.h),
        frames=model.frames + 1,
    )


def blend(a: np.ndarray, b: np.ndarray, r: float) -> np.ndarray:
    """``(1 - r) * a + r * b`` for two arrays of one shape and type (float32, float64, complex64
    or complex128), equal to numpy's bit for bit (the weights in the arrays' precision, as numpy
    2 casts a Python float), in one compiled pass instead of three.

    Examples
    --------
    >>> a, b = np.array([1.0, 2.0], np.float32), np.array([3.0, 6.0], np.float32)
    >>> blend(a, b, 0.25)
    array([1.5, 3. ], dtype=float32)
    """
    if a.shape != b.shape or a.dtype != b.dtype:
        raise ValueError(
            f"blend needs two arrays of one shape and type; got {a.dtype}{a.shape}, "
            f"{b.dtype}{b.shape}"
        )
    real = np.float32 if a.dtype in (np.float32, np.complex64) else np.float64
    out = np.empty(a.shape, a.dtype)
    _blend_into(
        np.ascontiguousarray(a).ravel(),
        np.ascontiguousarray(b).ravel(),
        real(1 - r),
        real(r),
        out.ravel(),
    )
    return out


@numba.njit(cache=True, boundscheck=False, nogil=True)
def _blend_into(a, b, keep, r, out):  # pragma: no cover (compiled)
    """``out = keep * a + r * b`` elementwise (flat arrays)."""
    for i in range(a.size):
        out[i] = keep * a[i] + r * b[i]


@cache
def warm_up() -> None:
    """Compile or load the feature kernels once per process."""
    _hog_cells(np.zeros((8, 8), np.float32), 4, 9, np.float32(0.2))
    features(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8), np.uint8), AppearanceConfig())
    features(np.zeros((8, 8, 3), np.uint8), None, AppearanceConfig())
    features(None, np.zeros((8, 8), np.uint8), AppearanceConfig())
    r = np.zeros((5, 5))
    _peak(r)
    _refine(0.0, 1.0, 0.0)
    _scale_peak(np.array([0.0, 1.0, 0.5]))
    _psr(r, 2, 2, 1)
    # the argument types the tracker passes: cached channel masks are read-only, the filter's
    # denominator is float32
    clipped = np.zeros(2, bool)
    clipped.flags.writeable = False
    _weigh(
        np.zeros((2, 2, 2), np.float32),
        np.ones(2, np.float32),
        clipped,
        1.0,
        np.ones((2, 2, 1), np.float32),
    )
    z = np.zeros((2, 2, 2), np.complex64)
    _correlate(z, z.astype(np.complex128), np.ones((2, 2), np.float32), 1)
    _scale_hog(
        np.zeros((8, 8), np.float32),
        0.0,
        0.0,
        4.0,
        4.0,
        4.0,
        4.0,
        np.ones(3),
        8,
        8,
        4,
        9,
        np.float32(0.2),
        np.ones(3, np.float32),
    )
    _unit_region(np.zeros((4, 4), np.uint8), 1, 3, 1, 3, np.float32(1.0 / 255.0))
    for dtype in (np.complex128, np.float32):  # the filters' numerators and denominators
        blend(np.zeros(2, dtype), np.zeros(2, dtype), 0.5)
    _moved_scales(np.ones((2, 3), np.float32), np.ones(3, np.float32), 0.5)
    _shifted(z, 0.5, 0.5, 2)
    _filter_terms(_label_fft(2, 2, 1.0, 1.0), z)
    fs = np.zeros((2, 3), np.complex64)
    num, den = _scale_terms(_scale_label_fft(5), fs)
    _scale_response(num, fs, den, np.float32(0.01))
