"""The dual tracker's colour cue: kernel-weighted histogram mean shift (the paper's step 2) and
the colour model's selective update (eq. 8-9)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages import kalman
from pipeline.stages.histogram import (
    HistogramConfig,
    appearance_bins,
    bhattacharyya,
    bright_fraction,
    ellipse_model,
    kernel_histogram,
    search_roi,
)
from pipeline.stages.meanshift import MeanShiftConfig, mean_shift
from pipeline.stages.model_update import (
    ModelUpdateConfig,
    UpdateDecision,
    selective_update,
    should_update_model,
)
from pipeline.stages.occlusion import nearer_overlapping
from pipeline.tracker_config import ColourConfig
from pipeline.trackers.dual.state import DualTarget
from pipeline.types import BBox


def add_time(timing: dict[str, float], key: str, t0: float) -> float:
    """Add the seconds since ``t0`` to ``timing[key]``; returns now."""
    now = time.perf_counter()
    timing[key] = timing.get(key, 0.0) + now - t0
    return now


def colour_image(frames: FramePair, mode: str) -> np.ndarray:
    """The image the colour cue works on: the visible frame, or the IR frame in the IR-only
    mode."""
    img = frames.infrared if mode == "ir" else frames.visible
    if img is None:
        raise ValueError(
            f"mode {mode!r} needs the {'infrared' if mode == 'ir' else 'visible'} frame"
        )
    return img


def backprojection_peak(
    bins: np.ndarray, q: np.ndarray, size: tuple[float, float]
) -> tuple[float, float] | None:
    """Centre (px of ``bins``) of the target-sized window holding the most model probability."""
    prob = q[bins].astype(np.float32)
    kw, kh = max(int(size[0]) | 1, 3), max(int(size[1]) | 1, 3)
    if prob.shape[0] < kh or prob.shape[1] < kw:
        return None
    dens = cv2.boxFilter(prob, -1, (kw, kh), borderType=cv2.BORDER_CONSTANT)
    r, c = np.unravel_index(int(np.argmax(dens)), dens.shape)
    return (c + 0.5, r + 0.5) if dens[r, c] > 0 else None


@dataclass(frozen=True)
class ColourStep:
    """The motion prior and the mean shift of a target in one frame (the paper's step 2).

    ``y0`` is where the search started, ``y1`` where the mean shift converged (``rho1`` its
    colour match, NaN where the colour cue did not run), ``bins`` the colour bin image of the
    search region whose corner is ``roi0`` (frame px).
    """

    t: DualTarget
    prior: kalman.GaussianState
    y0: tuple[float, float]
    y1: tuple[float, float]
    rho1: float
    informative: bool
    bright: float
    bins: np.ndarray | None
    roi0: tuple[int, int]
    ms_iters: int

    @property
    def box1(self) -> BBox:
        """The target's box at the mean-shift position y1."""
        return BBox.from_center(self.y1[0], self.y1[1], self.t.size[0], self.t.size[1])

    @property
    def box_prior(self) -> BBox:
        """The target's box at its predicted position."""
        return BBox.from_center(
            float(self.prior.x[0]), float(self.prior.x[1]), self.t.size[0], self.t.size[1]
        )

    @property
    def usable(self) -> bool:
        """The colour is seen and the region's bins exist (matches can be measured)."""
        return self.informative and self.bins is not None


@dataclass(frozen=True)
class ColourCue:
    """Mean shift on the kernel-weighted colour (or IR intensity) histogram, and its model.

    Parameters
    ----------
    cfg : ColourConfig
        ``dual.colour``: when the cue runs (dark frames) and its search region while missing.
    histogram : HistogramConfig
        ``dual.histogram``: the binning.
    meanshift : MeanShiftConfig
        ``dual.meanshift``: the iteration and the search margin.
    model_update : ModelUpdateConfig
        ``dual.model_update``: the selective update of eq. 8-9.
    """

    cfg: ColourConfig
    histogram: HistogramConfig
    meanshift: MeanShiftConfig
    model_update: ModelUpdateConfig

    def models(self, frames: FramePair, mode: str, boxes: list[BBox]) -> list[np.ndarray]:
        """The colour models of targets given at ``boxes`` on their first frame, each without
        the pixels of the nearer targets that overlap it where enough is left
        (``first_model_excludes_nearer``, ``first_model_min_uncovered``)."""
        bins, m = appearance_bins(colour_image(frames, mode), self.histogram)
        given = tuple(boxes) if self.cfg.first_model_excludes_nearer else ()
        out = []
        for i, b in enumerate(boxes):
            nearer = nearer_overlapping(given, i) if given else ()
            q = kernel_histogram(bins, b, m, nearer, self.cfg.first_model_min_uncovered)
            out.append(q if q.any() or not nearer else kernel_histogram(bins, b, m))
        return out

    def informative(self, image: np.ndarray, box: BBox) -> tuple[bool, float]:
        """Whether enough of the kernel's pixels are bright enough to carry colour (always True
        for IR, or without dark gating), and the bright share."""
        if image.ndim == 2 or not self.cfg.dark_gating:
            return True, 1.0
        h, w = image.shape[:2]
        x0, y0, x1, y1 = search_roi(box, 0.0, w, h)
        frac = bright_fraction(image[y0:y1, x0:x1], self.cfg.min_value)
        return frac >= self.cfg.min_fraction, frac

    def step(
        self,
        frames: FramePair,
        t: DualTarget,
        prior: kalman.GaussianState,
        y0: tuple[float, float],
        mode: str,
        timing: dict[str, float],
    ) -> ColourStep:
        """Mean shift from ``y0`` in the colour channel -> y1; a missing target is also searched
        from where the model's colours are densest in a region ``missing_search_scale`` times
        larger."""
        image = colour_image(frames, mode)
        kernel = BBox.from_center(y0[0], y0[1], t.size[0], t.size[1])
        clock = time.perf_counter()
        informative, bright = self.informative(image, kernel)
        rho1, ms_iters, y1, bins, roi0 = float("nan"), 0, y0, None, (0, 0)
        if informative:
            missing = t.missing > 0 or t.held
            H, W = image.shape[:2]
            margin = self.meanshift.search_margin * (
                self.cfg.missing_search_scale if missing else 1.0
            )
            x0, yy0, x1, yy1 = search_roi(kernel, margin, W, H)
            bins, _ = appearance_bins(np.ascontiguousarray(image[yy0:yy1, x0:x1]), self.histogram)
            roi0 = (x0, yy0)
            ms, ms_iters = self._shift(bins, t, (y0[0] - x0, y0[1] - yy0), missing)
            if not ms.no_support:
                y1 = (ms.center[0] + x0, ms.center[1] + yy0)
                rho1 = ms.rho
            else:
                rho1 = 0.0
        add_time(timing, "meanshift", clock)
        return ColourStep(t, prior, y0, y1, rho1, informative, bright, bins, roi0, ms_iters)

    def _shift(self, bins: np.ndarray, t: DualTarget, start: tuple[float, float], missing: bool):
        """The mean shift from ``start`` (and, for a missing target, from the back-projection's
        peak when it matches better); returns it and the iterations of both."""
        half = (t.size[0] / 2, t.size[1] / 2)
        ms = mean_shift(bins, t.q, start, half, self.meanshift)
        iters = ms.iterations
        if missing:
            peak = backprojection_peak(bins, t.q, t.size)
            if peak is not None:
                ms2 = mean_shift(bins, t.q, peak, half, self.meanshift)
                iters += ms2.iterations
                if not ms2.no_support and (ms.no_support or ms2.rho > ms.rho):
                    ms = ms2
        return ms, iters

    def match_at(self, cs: ColourStep, box: BBox | None, model: np.ndarray | None = None) -> float:
        """Bhattacharyya coefficient of the target's model (or ``model``, another target's) and
        the kernel histogram inside ``box`` (frame px); NaN where the colour is not seen, without
        a box, or when too little of the kernel lies in the search region."""
        if box is None or not cs.usable:
            return float("nan")
        assert cs.bins is not None
        q = cs.t.q if model is None else model
        p, n, mass = ellipse_model(
            cs.bins, box.cx - cs.roi0[0], box.cy - cs.roi0[1], box.w / 2, box.h / 2, q.size
        )
        if mass < self.meanshift.min_mass_fraction:
            return float("nan")
        return bhattacharyya(p, q) if n > 0 else 0.0

    def learn(
        self, cs: ColourStep, box: BBox, learn: bool, measured: bool
    ) -> tuple[np.ndarray, UpdateDecision, float]:
        """Eq. 8-9 with the histogram at the new ``box`` (the gate:
        :mod:`pipeline.stages.model_update`): (q, decision, rho2)."""
        q, bins, mu = cs.t.q, cs.bins, self.model_update
        if measured and bins is not None and not learn and mu.enabled:
            return q, UpdateDecision(False, "unconfirmed"), float("nan")
        if not measured or bins is None or not learn:
            no = should_update_model(0.0, not measured, bins is not None, learn, mu)
            return q, no, float("nan")
        p, _, mass = ellipse_model(
            bins, box.cx - cs.roi0[0], box.cy - cs.roi0[1], box.w / 2, box.h / 2, q.size
        )
        if mass < self.meanshift.min_mass_fraction:
            return q, UpdateDecision(False, "window-cut-by-border"), float("nan")
        rho2 = bhattacharyya(p, q)
        decision = should_update_model(rho2, False, True, True, mu)
        return (selective_update(q, p, mu) if decision.update else q), decision, rho2
