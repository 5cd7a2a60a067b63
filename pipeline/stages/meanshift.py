"""Kernel mean shift localisation (eq. 2-4 of the dual-channel paper; Comaniciu et al. 2003).

With the Epanechnikov profile, ``g = -k'`` is constant on the support, so one step is
the weighted centroid ``y1 = sum(w_i x_i) / sum(w_i)`` of the pixels with ``r^2 < 1``
around ``y0``, ``w_i = sqrt(q_u / p_u(y0))`` for ``u = b(x_i)`` (eq. 4). Steps are
halved while the Bhattacharyya coefficient drops (Comaniciu's step 5) and iteration
stops when the move is below ``epsilon_px`` (sub-pixel) or after ``max_iterations``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numba
import numpy as np
from numpy.typing import NDArray

from pipeline.params import Section, param
from pipeline.stages.histogram import (
    bhattacharyya,
    bhattacharyya_kernel,
    ellipse_model,
    ellipse_model_kernel,
    ellipse_shift,
)
from pipeline.stages.histogram import warm_up as histogram_warm_up


@dataclass(frozen=True)
class MeanShiftConfig(Section):
    """Mean-shift iteration and scale search.

    Parameters
    ----------
    max_iterations : int
        Iteration cap per localisation, >= 1; default 20. Increasing it lets the window
        travel further per frame at a higher worst-case cost.
    epsilon_px : float
        Stop when the window moves less than this, px, in (0, 5]; default 0.2. The
        paper stops when y0 and y1 fall in the same pixel; near the optimum the steps
        shrink geometrically. Decreasing it refines the position at the cost of
        iterations.
    max_halvings : int
        Step-halving attempts per iteration when rho drops, >= 0; default 6.
    scale_step : float
        Relative size change tried by the scale search (the paper's comparison
        method uses +-10 %), in [0, 0.5]; default 0.1. 0 disables the search.
    scale_rate : float
        Blend rate of the best scale into the current one, ``h = r*h_opt + (1-r)*h``,
        in [0, 1]; default 0.1. Increasing it follows size changes faster and lets
        clutter shrink the window sooner.
    min_mass_fraction : float
        Share of the kernel mass that must lie inside the frame for the match to be
        trusted, in [0, 1]; default 0.5.
    search_margin : float
        Half-size of the region examined around the window, in box sizes, in [0.5, 5];
        default 1.5. Increasing it tolerates larger motion per frame at a cost that
        grows with the area examined.
    """

    section = "meanshift"

    max_iterations: int = param(20, ge=1)
    epsilon_px: float = param(0.2, gt=0, le=5)
    max_halvings: int = param(6, ge=0)
    scale_step: float = param(0.1, ge=0, le=0.5)
    scale_rate: float = param(0.1, ge=0, le=1)
    min_mass_fraction: float = param(0.5, ge=0, le=1)
    search_margin: float = param(1.5, ge=0.5, le=5)


@dataclass(frozen=True)
class MeanShiftIter:
    """State passed to ``iter_callback`` after each iteration."""

    iteration: int
    center: tuple[float, float]
    rho: float


@dataclass(frozen=True)
class MeanShiftResult:
    """Outcome of one mean-shift localisation.

    ``center`` is in the px of the bin image passed in. ``converged`` is False when the
    iteration cap was hit; ``no_support`` when no pixel of the window carries a model
    colour (sum of weights zero), in which case ``center`` is the start point.
    """

    center: tuple[float, float]
    rho: float
    p: NDArray[np.float64]
    iterations: int
    converged: bool
    halvings: int
    mass_fraction: float
    no_support: bool


def _model(
    bins: NDArray[np.int32], c: tuple[float, float], half: tuple[float, float], m: int
) -> tuple[NDArray[np.float64], int, float]:
    return ellipse_model(bins, c[0], c[1], half[0], half[1], m)


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")
def _mean_shift_kernel(bins, q, x, y, hx, hy, max_iterations, eps2, max_halvings):
    # pragma: no cover (compiled)
    """:func:`mean_shift`'s loop in one compiled call, the same arithmetic in the same order:
    ``(x, y, rho, p, iterations, converged, halvings, mass_fraction, no_support)``."""
    m = q.shape[0]
    p0, n0, mass0 = ellipse_model_kernel(bins, x, y, hx, hy, m)
    rho0 = bhattacharyya_kernel(p0, q)
    halvings = 0
    ratio = np.zeros(m, np.float64)
    for it in range(1, max_iterations + 1):
        if n0 == 0:
            return x, y, rho0, p0, it - 1, False, halvings, 0.0, True
        for u in range(m):
            ratio[u] = np.sqrt(q[u] / p0[u]) if p0[u] > 0 else 0.0
        ws, wx, wy = ellipse_shift(bins, ratio, x, y, hx, hy)
        if ws <= 0:
            return x, y, rho0, p0, it - 1, False, halvings, mass0, True
        x1, y1 = wx / ws, wy / ws
        p1, n1, mass1 = ellipse_model_kernel(bins, x1, y1, hx, hy, m)
        rho1 = bhattacharyya_kernel(p1, q)
        n_half = 0
        while rho1 < rho0 and n_half < max_halvings:
            if (x1 - x) * (x1 - x) + (y1 - y) * (y1 - y) < eps2:
                break
            x1, y1 = 0.5 * (x + x1), 0.5 * (y + y1)
            p1, n1, mass1 = ellipse_model_kernel(bins, x1, y1, hx, hy, m)
            rho1 = bhattacharyya_kernel(p1, q)
            n_half += 1
        halvings += n_half
        moved2 = (x1 - x) * (x1 - x) + (y1 - y) * (y1 - y)
        x, y, n0, p0, rho0, mass0 = x1, y1, n1, p1, rho1, mass1
        if moved2 < eps2:
            return x, y, rho0, p0, it, True, halvings, mass0, False
    return x, y, rho0, p0, max_iterations, False, halvings, mass0, False


def mean_shift(
    bins: NDArray[np.int32],
    q: NDArray[np.float64],
    start: tuple[float, float],
    half_size: tuple[float, float],
    cfg: MeanShiftConfig,
    iter_callback: Callable[[MeanShiftIter], None] | None = None,
) -> MeanShiftResult:
    """Locate the window maximising the Bhattacharyya coefficient with the model ``q``.

    Parameters
    ----------
    bins : (H, W) int32
        Bin-index image of the search region.
    q : (m,) float64
        Target model, normalized.
    start : (x, y)
        Start centre y0 in the px of ``bins``.
    half_size : (hx, hy)
        Kernel half-axes, px (the box's w/2, h/2).
    cfg : MeanShiftConfig
        Iteration settings.
    iter_callback : callable, optional
        Called with a :class:`MeanShiftIter` after every iteration.

    Returns
    -------
    MeanShiftResult
    """
    if bins.ndim != 2:
        raise ValueError(f"bins must be 2-D; got shape {bins.shape}")
    m = q.shape[0]
    if iter_callback is None and q.ndim == 1 and q.dtype == np.float64 and half_size[0] > 0:
        if half_size[1] > 0:  # the loop below, compiled
            x, y, rho, p, it, conv, halv, mass, nosup = _mean_shift_kernel(
                bins,
                q,
                float(start[0]),
                float(start[1]),
                float(half_size[0]),
                float(half_size[1]),
                cfg.max_iterations,
                cfg.epsilon_px**2,
                cfg.max_halvings,
            )
            return MeanShiftResult(
                (float(x), float(y)),
                float(rho),
                p,
                int(it),
                bool(conv),
                int(halv),
                float(mass),
                bool(nosup),
            )
    y0 = (float(start[0]), float(start[1]))
    p0, n0, mass0 = _model(bins, y0, half_size, m)
    rho0 = bhattacharyya(p0, q)
    halvings = 0
    eps2 = cfg.epsilon_px**2
    for it in range(1, cfg.max_iterations + 1):
        if n0 == 0:
            return MeanShiftResult(y0, rho0, p0, it - 1, False, halvings, 0.0, True)
        ratio = np.zeros(m, np.float64)
        nz = p0 > 0
        ratio[nz] = np.sqrt(q[nz] / p0[nz])
        ws, wx, wy = ellipse_shift(
            bins, ratio, y0[0], y0[1], float(half_size[0]), float(half_size[1])
        )
        if ws <= 0:
            return MeanShiftResult(y0, rho0, p0, it - 1, False, halvings, mass0, True)
        y1 = (wx / ws, wy / ws)
        p1, n1, mass1 = _model(bins, y1, half_size, m)
        rho1 = bhattacharyya(p1, q)
        n_half = 0
        while rho1 < rho0 and n_half < cfg.max_halvings:
            if (y1[0] - y0[0]) ** 2 + (y1[1] - y0[1]) ** 2 < eps2:
                break
            y1 = (0.5 * (y0[0] + y1[0]), 0.5 * (y0[1] + y1[1]))
            p1, n1, mass1 = _model(bins, y1, half_size, m)
            rho1 = bhattacharyya(p1, q)
            n_half += 1
        halvings += n_half
        moved2 = (y1[0] - y0[0]) ** 2 + (y1[1] - y0[1]) ** 2
        y0, n0, p0, rho0, mass0 = y1, n1, p1, rho1, mass1
        if iter_callback is not None:
            iter_callback(MeanShiftIter(it, y0, rho0))
        if moved2 < eps2:
            return MeanShiftResult(y0, rho0, p0, it, True, halvings, mass0, False)
    return MeanShiftResult(y0, rho0, p0, cfg.max_iterations, False, halvings, mass0, False)


@dataclass(frozen=True)
class ScaleSearchResult:
    """Mean shift run at the current size and at ``1 +- scale_step`` of it."""

    best: MeanShiftResult
    best_factor: float
    iterations: int


def mean_shift_scale_search(
    bins: NDArray[np.int32],
    q: NDArray[np.float64],
    start: tuple[float, float],
    half_size: tuple[float, float],
    cfg: MeanShiftConfig,
) -> ScaleSearchResult:
    """Comaniciu's scale adaptation: localise with h, (1+s)h and (1-s)h, keep the best rho.

    The caller blends the winning factor in with ``cfg.scale_rate``.
    """
    factors = (1.0,) if cfg.scale_step == 0 else (1.0, 1.0 + cfg.scale_step, 1.0 - cfg.scale_step)
    best: MeanShiftResult | None = None
    best_f = 1.0
    total = 0
    for f in factors:
        r = mean_shift(bins, q, start, (half_size[0] * f, half_size[1] * f), cfg)
        total += r.iterations
        if best is None or (not r.no_support and r.rho > best.rho):
            best, best_f = r, f
    assert best is not None  # factors is never empty
    return ScaleSearchResult(best, best_f, total)


@cache
def warm_up() -> None:
    """Compile (first run) or load from numba's cache the histogram loops and the mean-shift
    loop, for both bin images (colour int32, intensity uint8), so that a tracker's first frame
    does not pay for them (about 7 ms from the cache). Runs once per process."""
    histogram_warm_up()
    for dtype in (np.int32, np.uint8):
        _mean_shift_kernel(np.zeros((4, 4), dtype), np.ones(2), 2.0, 2.0, 1.5, 1.5, 2, 0.01, 2)
