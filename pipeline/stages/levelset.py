"""DRLSE: distance-regularized level-set evolution (Li, Xu, Gui, Fox 2010; eq. 5-6 of the
dual-channel paper).

Energy ``E(phi) = mu R_p(phi) + lambda L_g(phi) + alpha A_g(phi)`` with the double-well
potential ``p2``, edge indicator ``g = 1 / (1 + |grad(G_sigma * I)|^2 / kappa^2)`` and
inside = ``phi < 0``. Gradient flow (one explicit step of size ``dt``)::

    phi += dt * (mu * div(d_p(|grad phi|) grad phi)
                 + lambda * delta_eps(phi) * (grad g . N + g * div N)
                 + alpha * g * delta_eps(phi)),      N = grad phi / |grad phi|

discretized as Li's reference code (docs/algorithms.md §1.4): Neumann border by mirroring the
first interior row/column, central differences, the distance term written
``div((d_p - 1) grad phi) + laplacian(phi)``. ``kappa = 1`` is the paper's ``g``; a larger
``kappa`` keeps weak (low-contrast IR) edges able to stop the front.

Two implementations of the same update: :func:`evolve_reference` (vectorized numpy, the
test oracle) and a numba kernel that visits only a narrow band around the zero level set
(pixels whose 5x5 neighbourhood is flat and away from the front do not change). The
tracker uses :func:`evolve`, which runs the numba kernel with a stopping rule: every
``check_every`` iterations the inside area is compared with its value ``stop_window``
iterations earlier, and the evolution stops once it changes by less than
``stop_tolerance`` (relative); ``refine_iterations`` more with ``alpha = 0`` follow.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, lru_cache

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from pipeline.params import Section, param


@dataclass(frozen=True)
class LevelSetConfig(Section):
    """DRLSE parameters (docs/algorithms.md §0 and §1.5-1.7 give the defaults' sources).

    Parameters
    ----------
    timestep : float
        Delta t of the explicit scheme, in (0, 10]; default 5. ``distance_weight *
        timestep`` must stay below 0.25 (stability of the regularization).
    distance_weight : float
        mu, weight of the distance-regularization term, > 0; default 0.04 (= 0.2/dt).
    length_weight : float
        lambda, weight of the g-weighted length term, >= 0; default 5. Increasing it
        gives smoother contours and cuts thin parts (arms, legs) sooner.
    area_weight : float
        alpha, weight of the g-weighted area (balloon) term; default 0.6: positive
        shrinks a contour that starts outside the target. Increasing it moves the front
        faster and lets it leak through weak edges (soft IR edges and thin limbs want
        less than the demos' 1.5). (The paper's alpha; the scale and model learning rates
        have their own names.)
    area_weight_warm : float
        alpha for warm starts, which begin ``contour.warm_dilate_px`` outside the
        previous contour and shrink back onto the edges; default 0.6. 0 lets a warm
        contour only erode.
    dirac_width : float
        epsilon of the smoothed Dirac delta, px, > 0; default 1.5.
    smoothing_sigma_px : float
        sigma of the Gaussian applied to the IR intensities (0..255) before the edge
        indicator, px, > 0; default 0.8 (the gourd demo's; thermal edges are soft already).
    edge_scale : float
        kappa in ``g = 1/(1 + |grad|^2/kappa^2)``, grey levels per px, > 0; default 1
        (the paper's g). Increasing it lets weaker edges count; see ``edge_scale_auto``.
    edge_scale_auto : bool
        Beyond the paper: kappa = max(edge_scale, 3 x the median gradient magnitude of
        the ROI), so that noise alone never looks like an edge; default True.
    step_height : float
        c0 of the binary-step initialisation (phi = -c0 inside, +c0 outside), > 0 and
        > ``dirac_width``; default 2.
    max_iterations_cold : int
        Iteration cap from a binary step, >= 1; default 300.
    max_iterations_warm : int
        Iteration cap from the previous frame's level-set function, >= 1; default 15
        (warm starts begin a pixel or two from the edges). With the default stopping rule
        (a check every 5 iterations against the area 10 iterations earlier) the first
        possible stop is at iteration 15, so warm starts run the full 15.
    refine_iterations : int
        Iterations with alpha = 0 after convergence, >= 0; default 5.
    check_every : int
        Iterations between two checks of the stopping rule, >= 1; default 5.
    stop_window : int
        The area is compared with its value this many iterations earlier, >= 1
        and >= ``check_every``; default 10.
    stop_tolerance : float
        Relative area change below which the evolution has converged, in (0, 1);
        default 0.002 (0.2 %), at least one pixel.
    band_px : float
        Narrow band: pixels with |phi| below this or a sign change to a neighbour, and
        their 1-pixel neighbourhood, are updated, px, > 0 and > ``dirac_width``; default 1.9 (just
        under c0, so the flat +-c0 regions are skipped until the front reaches them).
    """

    section = "levelset"

    timestep: float = param(5.0, gt=0, le=10)
    distance_weight: float = param(0.04, gt=0)
    length_weight: float = param(5.0, ge=0)
    area_weight: float = param(0.6)
    area_weight_warm: float = param(0.6)
    dirac_width: float = param(1.5, gt=0)
    smoothing_sigma_px: float = param(0.8, gt=0)
    edge_scale: float = param(1.0, gt=0)
    edge_scale_auto: bool = True
    step_height: float = param(2.0, gt=0)
    max_iterations_cold: int = param(300, ge=1)
    max_iterations_warm: int = param(15, ge=1)
    refine_iterations: int = param(5, ge=0)
    check_every: int = param(5, ge=1)
    stop_window: int = param(10, ge=1)
    stop_tolerance: float = param(0.002, gt=0, lt=1)
    band_px: float = param(1.9, gt=0)

    def check(self) -> None:
        if not self.distance_weight * self.timestep < 0.25:
            raise ValueError(
                "levelset.distance_weight x levelset.timestep must be < 0.25 for stability; got "
                f"{self.distance_weight} x {self.timestep} = "
                f"{self.distance_weight * self.timestep:g}"
            )
        if not self.step_height > self.dirac_width:
            raise ValueError("levelset.step_height must exceed levelset.dirac_width")
        if not self.stop_window >= self.check_every:
            raise ValueError("levelset.stop_window must be an integer >= levelset.check_every")
        if not self.band_px > self.dirac_width:
            raise ValueError("levelset.band_px must exceed levelset.dirac_width")


@dataclass(frozen=True)
class EdgeMap:
    """Edge indicator ``g`` of an IR region and its gradient (float32, same shape)."""

    g: NDArray[np.float32]
    gx: NDArray[np.float32]
    gy: NDArray[np.float32]
    kappa: float


def _central_diff(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d/dx, d/dy) by central differences (np.gradient: one-sided at the border)."""
    dy, dx = np.gradient(a)
    return dx.astype(np.float32), dy.astype(np.float32)


def _central_diff_fast(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d/dx, d/dy) by central differences, replicated border, float32: the values of
    ``cv2.Sobel(a, CV_32F, 1, 0 / 0, 1, ksize=1, scale=0.5, BORDER_REPLICATE)`` (tested equal) in
    one compiled pass instead of two OpenCV calls (7 vs 38 us on a 96x48 region)."""
    return _diff_pair(np.ascontiguousarray(a, dtype=np.float32))


@numba.njit(
    cache=True, boundscheck=False, nogil=True, error_model="numpy"
)  # no fastmath: the same float32 arithmetic as OpenCV's
def _diff_pair(a):  # pragma: no cover (compiled)
    """Flat unsigned indices (no wrap-around checks), the interior of each row in one loop."""
    H, W = a.shape
    af = a.reshape(H * W)
    dx = np.empty((H, W), np.float32)
    dy = np.empty((H, W), np.float32)
    xf = dx.reshape(H * W)
    yf = dy.reshape(H * W)
    half = np.float32(0.5)
    uW = np.uint64(W)
    u1 = np.uint64(1)
    for i in range(H):
        b = np.uint64(i) * uW
        bm = np.uint64(max(i - 1, 0)) * uW
        bp = np.uint64(min(i + 1, H - 1)) * uW
        for j in range(uW):
            yf[b + j] = (af[bp + j] - af[bm + j]) * half
        if W == 1:
            xf[b] = (af[b] - af[b]) * half
            continue
        xf[b] = (af[b + u1] - af[b]) * half
        for j in range(u1, uW - u1):
            xf[b + j] = (af[b + j + u1] - af[b + j - u1]) * half
        xf[b + uW - u1] = (af[b + uW - u1] - af[b + uW - u1 - u1]) * half
    return dx, dy


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")  # no fastmath
def _edge_kernel(f, edge_scale, auto):  # pragma: no cover (compiled)
    """:func:`edge_map` after the smoothing, in one compiled call with numpy's float32
    arithmetic: ``|grad f|^2``, the automatic kappa (3 x the square root of the median of
    every other pixel of every other row: the element a partition selects, whatever the
    algorithm), ``g`` and its gradient."""
    ix, iy = _diff_pair(f)
    H, W = f.shape
    mag2 = ix * ix + iy * iy
    kappa = edge_scale
    if auto:
        sample = np.empty(((H + 1) // 2) * ((W + 1) // 2), np.float32)
        n = 0
        for i in range(0, H, 2):
            for j in range(0, W, 2):
                sample[n] = mag2[i, j]
                n += 1
        med = np.partition(sample, n // 2)[n // 2]
        kappa = max(kappa, 3.0 * float(np.sqrt(med)))
    c = np.float32(1.0 / (kappa * kappa))
    one = np.float32(1.0)
    g = np.empty((H, W), np.float32)
    for i in range(H):
        for j in range(W):
            g[i, j] = one / (one + mag2[i, j] * c)
    gx, gy = _diff_pair(g)
    return g, gx, gy, kappa


def edge_map(ir: np.ndarray, cfg: LevelSetConfig) -> EdgeMap:
    """g = 1/(1 + |grad(G_sigma * I)|^2 / kappa^2) on 0..255 intensities, and grad g.

    Smoothing uses a reflecting border (a zero-padded blur would create false edges at
    the ROI border; docs/algorithms.md §1.4). Derivatives are central differences (OpenCV,
    replicated border); the median for the automatic kappa is taken on every other
    pixel of every other row.
    """
    if ir.ndim != 2:
        raise ValueError(f"ir must be a (H, W) image; got shape {ir.shape}")
    f = cv2.GaussianBlur(
        ir.astype(np.float32), (0, 0), cfg.smoothing_sigma_px, borderType=cv2.BORDER_REFLECT
    )
    g, gx, gy, kappa = _edge_kernel(f, float(cfg.edge_scale), bool(cfg.edge_scale_auto))
    return EdgeMap(g, gx, gy, kappa)


def binary_step(shape: tuple[int, int], inside: np.ndarray, c0: float) -> NDArray[np.float32]:
    """phi0 = -c0 where ``inside`` (bool mask), +c0 elsewhere."""
    phi = np.full(shape, c0, np.float32)
    phi[inside] = -c0
    return phi


def box_step(
    shape: tuple[int, int], box: tuple[float, float, float, float], c0: float
) -> NDArray[np.float32]:
    """phi0 = -c0 inside the box ``(x, y, w, h)`` (pixels whose centre lies in it), +c0 outside.

    The box is kept at least 2 px inside the array so the Neumann border stays clear.
    """
    h, w = shape
    x0 = max(round(box[0]), 2)
    y0 = max(round(box[1]), 2)
    x1 = min(round(box[0] + box[2]), w - 2)
    y1 = min(round(box[1] + box[3]), h - 2)
    phi = np.full(shape, c0, np.float32)
    if x1 > x0 and y1 > y0:
        phi[y0:y1, x0:x1] = -c0
    return phi


# --------------------------------------------------------------------------- reference
def _neumann(phi: np.ndarray) -> None:
    phi[0, :] = phi[2, :]
    phi[-1, :] = phi[-3, :]
    phi[:, 0] = phi[:, 2]
    phi[:, -1] = phi[:, -3]


def _dirac(x: np.ndarray, eps: float) -> np.ndarray:
    return np.where(
        np.abs(x) <= eps, (1.0 / (2 * eps)) * (1 + np.cos(np.pi * x / eps)), 0.0
    ).astype(np.float32)


def _dp2(s: np.ndarray) -> np.ndarray:
    """d_p(s) = p2'(s)/s for the double-well potential (1 at s = 0)."""
    return np.where(s < 1.0, np.sinc(2.0 * s), 1.0 - 1.0 / np.maximum(s, 1.0)).astype(np.float32)


def reference_step(phi: np.ndarray, em: EdgeMap, cfg: LevelSetConfig, alpha: float) -> np.ndarray:
    """One DRLSE iteration, vectorized numpy (Li's reference discretization). Returns the new
    phi."""
    phi = phi.astype(np.float32, copy=True)
    _neumann(phi)
    px, py = _central_diff(phi)
    s = np.sqrt(px * px + py * py)
    nx = px / (s + 1e-10)
    ny = py / (s + 1e-10)
    nxx, _ = _central_diff(nx)
    _, nyy = _central_diff(ny)
    curv = nxx + nyy
    dps = _dp2(s)
    fx, _ = _central_diff((dps - 1.0) * px)
    _, fy = _central_diff((dps - 1.0) * py)
    lap = cv2.Laplacian(phi, cv2.CV_32F, ksize=1, borderType=cv2.BORDER_REPLICATE)
    dist = fx + fy + lap
    de = _dirac(phi, cfg.dirac_width)
    edge = de * (em.gx * nx + em.gy * ny + em.g * curv)
    area = em.g * de
    return phi + np.float32(cfg.timestep) * (
        np.float32(cfg.distance_weight) * dist
        + np.float32(cfg.length_weight) * edge
        + np.float32(alpha) * area
    )


def evolve_reference(
    phi0: np.ndarray, em: EdgeMap, cfg: LevelSetConfig, iterations: int, alpha: float | None = None
) -> np.ndarray:
    """``iterations`` reference steps (no stopping rule): the oracle for the fast kernel."""
    phi = phi0.astype(np.float32, copy=True)
    a = cfg.area_weight if alpha is None else alpha
    for _ in range(iterations):
        phi = reference_step(phi, em, cfg, a)
    return phi


# --------------------------------------------------------------------------- fast kernel
POLY_DEGREE = 8

FASTMATH = {"nnan", "ninf", "nsz", "arcp", "contract", "reassoc"}
"""The band kernel's LLVM fast-math flags: ``fastmath=True`` without ``afn`` (which lets LLVM
approximate square roots); reciprocals may still be approximated (``arcp``)."""


def _chebyshev_fit(f: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """float32 coefficients (constant first) of the polynomial of degree :data:`POLY_DEGREE` in
    ``x = 2 t - 1`` that interpolates ``f(t)`` at Chebyshev nodes of t in [0, 1]. In x the
    coefficients stay under 1, so that float32 Horner steps do not cancel."""
    n = 4 * POLY_DEGREE + 4
    t = 0.5 - 0.5 * np.cos(np.pi * (np.arange(n) + 0.5) / n)
    c = np.polynomial.chebyshev.chebfit(2 * t - 1, f(t), POLY_DEGREE)
    return np.polynomial.chebyshev.cheb2poly(c).astype(np.float32)


@lru_cache(maxsize=8)
def _polynomials(eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Polynomials (:func:`_chebyshev_fit`) of d_p(s) = sin(2 pi s)/(2 pi s) in t = s^2 on s in
    [0, 1], and of delta_eps(p) = (1 + cos(pi p / eps)) / (2 eps) in t = (p / eps)^2 on |p| <=
    eps (both are even). Evaluated in float32 their error is under 4e-7 (1e-7 per unit of
    delta_eps's peak 1 / eps), about float32's rounding of phi, and without a table lookup the
    kernel's loops run in vector registers."""
    dps = _chebyshev_fit(lambda t: np.sinc(2.0 * np.sqrt(t)))
    de = _chebyshev_fit(lambda t: (1.0 + np.cos(np.pi * np.sqrt(t))) / (2.0 * eps))
    dps.flags.writeable = False
    de.flags.writeable = False
    return dps, de


@numba.njit(cache=True, inline="always", nogil=True, error_model="numpy")
def _poly(t, c):  # pragma: no cover (compiled)
    """:func:`_polynomials`' polynomial ``c`` at ``t`` in [0, 1] (float32 Horner in ``x = 2 t -
    1``, unrolled so that a loop over pixels vectorises)."""
    x = np.float32(2.0) * t - np.float32(1.0)
    return (
        ((((((c[8] * x + c[7]) * x + c[6]) * x + c[5]) * x + c[4]) * x + c[3]) * x + c[2]) * x
        + c[1]
    ) * x + c[0]


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")
def _mirror_border(phi):  # pragma: no cover (compiled)
    """Neumann border in place, as :func:`_neumann`: the outer rows/columns copy the second ones
    in."""
    H, W = phi.shape
    for j in range(W):
        phi[0, j] = phi[2, j]
        phi[H - 1, j] = phi[H - 3, j]
    for i in range(H):
        phi[i, 0] = phi[i, 2]
        phi[i, W - 1] = phi[i, W - 3]


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")
def _any_negative(a):  # pragma: no cover (compiled)
    for k in range(a.size):
        if a[k] < 0:
            return True
    return False


@numba.njit(
    cache=True, boundscheck=False, fastmath=True, inline="always", nogil=True, error_model="numpy"
)
def _near_at(pf, k, i, j, H, uW, band):  # pragma: no cover (compiled)
    """The band test of one pixel with its neighbours inside the array only."""
    u1 = np.uint64(1)
    p = pf[k]
    v = abs(p) < band
    if not v and j + u1 < uW:
        v = p * pf[k + u1] <= 0
    if not v and j > np.uint64(0):
        v = p * pf[k - u1] <= 0
    if not v and i + 1 < H:
        v = p * pf[k + uW] <= 0
    if not v and i > 0:
        v = p * pf[k - uW] <= 0
    return np.uint8(v)


@numba.njit(
    cache=True,
    boundscheck=False,
    fastmath=FASTMATH,
    inline="always",
    nogil=True,
    error_model="numpy",
)
def _derivatives_at(pf, nx, ny, qx, qy, k, i, j, H, uW, dps_c):  # pragma: no cover (compiled)
    """The unit normal and the distance term's flux at one pixel of the array's outer ring
    (one-sided differences across the array's edge, central ones along it)."""
    u0, u1 = np.uint64(0), np.uint64(1)
    half, one, tiny = np.float32(0.5), np.float32(1.0), np.float32(1e-10)
    if j == u0:
        dx = pf[k + u1] - pf[k]
    elif j == uW - u1:
        dx = pf[k] - pf[k - u1]
    else:
        dx = half * (pf[k + u1] - pf[k - u1])
    if i == 0:
        dy = pf[k + uW] - pf[k]
    elif i == H - 1:
        dy = pf[k] - pf[k - uW]
    else:
        dy = half * (pf[k + uW] - pf[k - uW])
    s2 = dx * dx + dy * dy
    s = np.sqrt(s2)
    inv = one / (s + tiny)
    nx[k] = dx * inv
    ny[k] = dy * inv
    dps = _poly(s2, dps_c) if s < one else one - inv  # s + tiny == s for s >= 1
    qx[k] = (dps - one) * dx
    qy[k] = (dps - one) * dy


# error_model numpy: no zero test before each division (none divides by zero: 1 / (s + tiny), 1 / s
# for s >= 1)
@numba.njit(cache=True, boundscheck=False, fastmath=FASTMATH, error_model="numpy", nogil=True)
def _band_iterations(
    phi,
    g,
    gx,
    gy,
    n_iter,
    mu,
    lam,
    alpha,
    eps,
    dt,
    band,
    dps_c,
    de_c,
    check_every,
    stop_back,
    stop_tol,
    areas,
    n_refine,
):  # pragma: no cover
    """``n_iter`` DRLSE iterations in place on ``phi`` (float32), updating only a narrow band.

    The arithmetic of :func:`reference_step` in float32, with d_p and delta_eps as
    polynomials (:func:`_polynomials`) and under ``fastmath`` (reciprocals and square roots
    may be approximated): equal to the reference within float32 rounding, not bit for bit.
    ``near``: |phi| < band or a sign change to a neighbour; phi is updated on its 1-pixel
    dilation (so a flat pixel beside the band can join it as the front moves) and the
    derivatives that update needs are computed on its 2-pixel dilation; flat pixels further
    away keep their value. The band moves at most one pixel per iteration, so each
    iteration scans only the previous band's bounding box grown by two pixels. Every pass
    runs over the box without branches in its interior, so that it runs in vector
    registers: ``near`` (the outer rows and columns test only the neighbours inside the
    array), the dilations, the derivatives (on every interior pixel of the box: a value
    outside the 2-pixel dilation is never read; the array's outer ring, where the
    dilation reaches it, with one-sided differences) and the update (a select between the
    new value on the 1-pixel dilation and the old one elsewhere).

    Every array is indexed flat with unsigned offsets: numba checks each signed index for
    a negative value to wrap around, which would keep the loops scalar.

    With ``check_every > 0`` the stopping rule runs inside: every ``check_every``
    iterations the inside area is stored in ``areas`` and the loop ends once it differs
    by at most ``max(1, stop_tol * area)`` from the value ``stop_back`` checks earlier, or
    is 0. Then, if anything is inside, ``n_refine`` more iterations with ``alpha = 0`` (the
    refinement; in the same call, so the band carries over). Returns (iterations of the main
    phase, checks stored, whether the refinement ran).

    ``near`` and the dilations are left uninitialised: every value is written before it is
    read (``near`` on the whole array in the first iteration, the rest inside the box they
    are read in); the derivatives start at zero, because the update's select also reads them
    (and discards what it computes) beside the dilation.
    """
    H, W = phi.shape
    u0, u1, u2 = np.uint64(0), np.uint64(1), np.uint64(2)
    uW = np.uint64(W)
    uWm1 = uW - u1
    pf = phi.reshape(H * W)  # a view (phi is C-contiguous); numba refuses otherwise
    gf = g.ravel()
    gxf = gx.ravel()
    gyf = gy.ravel()
    near = np.empty(H * W, np.uint8)
    t2 = np.empty(H * W, np.uint8)
    t1 = np.empty(H * W, np.uint8)
    a2 = np.empty(H * W, np.uint8)
    a1 = np.empty(H * W, np.uint8)
    nx = np.zeros(H * W, np.float32)
    ny = np.zeros(H * W, np.float32)
    qx = np.zeros(H * W, np.float32)
    qy = np.zeros(H * W, np.float32)
    new = np.empty(H * W, np.float32)
    colany = np.empty(W, np.uint8)
    half = np.float32(0.5)
    one = np.float32(1.0)
    tiny = np.float32(1e-10)
    inv_eps = np.float32(1.0) / eps
    r0, r1, c0, c1 = 0, H - 1, 0, W - 1
    done = 0
    n_checks = 0
    left = n_iter  # iterations left in the current phase
    refining = False
    a = alpha
    while True:
        if not refining:
            stop = left == 0
            if not stop and check_every > 0 and done > 0 and done % check_every == 0:
                area = 0
                for k in range(H * W):
                    if pf[k] < 0:
                        area += 1
                areas[n_checks] = area
                n_checks += 1
                if area == 0:
                    break
                stop = n_checks > stop_back and abs(area - areas[n_checks - 1 - stop_back]) <= max(
                    1.0, stop_tol * area
                )
            if stop:  # the main phase is over: refine with alpha = 0 if anything is inside
                _mirror_border(phi)
                if n_refine == 0 or not _any_negative(pf):
                    break
                refining = True
                left = n_refine
                a = np.float32(0.0)
        if left == 0:
            break
        left -= 1
        if not refining:
            done += 1
        _mirror_border(phi)
        # near over the scan box and its bounding box: the interior branch-free (vectorises), the
        # outer rows and columns with their one-sided neighbour tests
        b0, b1, d0, d1 = H, -1, W, -1
        uc0, uc1 = np.uint64(c0), np.uint64(c1)
        for j in range(uc0, uc1 + u1):
            colany[j] = 0
        J0, J1 = np.uint64(max(c0, 1)), np.uint64(min(c1, W - 2))
        for i in range(r0, r1 + 1):
            base = np.uint64(i) * uW
            rowany = np.uint8(0)
            if i == 0 or i == H - 1:
                for j in range(uc0, uc1 + u1):
                    v = _near_at(pf, base + j, i, j, H, uW, band)
                    near[base + j] = v
                    rowany |= v
                    colany[j] |= v
            else:
                if c0 == 0:
                    v = _near_at(pf, base, i, u0, H, uW, band)
                    near[base] = v
                    rowany |= v
                    colany[0] |= v
                for j in range(J0, J1 + u1):
                    k = base + j
                    p = pf[k]
                    v = np.uint8(
                        (abs(p) < band)
                        | (p * pf[k + u1] <= 0)
                        | (p * pf[k - u1] <= 0)
                        | (p * pf[k + uW] <= 0)
                        | (p * pf[k - uW] <= 0)
                    )
                    near[k] = v
                    rowany |= v
                    colany[j] |= v
                if c1 == W - 1 and W > 1:
                    v = _near_at(pf, base + uWm1, i, uWm1, H, uW, band)
                    near[base + uWm1] = v
                    rowany |= v
                    colany[uWm1] |= v
            if rowany:
                b0 = min(b0, i)
                b1 = max(b1, i)
        for j in range(c0, c1 + 1):
            if colany[j]:
                d0 = j
                break
        for j in range(c1, c0 - 1, -1):
            if colany[j]:
                d1 = j
                break
        if b1 < 0:  # nothing near a zero level: nothing moves any more, in either phase
            if not refining:
                _mirror_border(phi)
                refining = n_refine > 0 and _any_negative(pf)
            break
        R0, R1, C0, C1 = max(b0 - 2, 0), min(b1 + 2, H - 1), max(d0 - 2, 0), min(d1 + 2, W - 1)
        uC0, uC1 = np.uint64(C0), np.uint64(C1)
        J0, J1 = np.uint64(max(C0, 2)), np.uint64(min(C1, W - 3))
        # separable dilations of near, radius 1 (update) and 2 (derivatives)
        for i in range(R0, R1 + 1):
            base = np.uint64(i) * uW
            for j in range(uC0, min(J0, uC1 + u1)):
                k = base + j
                m1 = near[k] | near[base + max(j, u1) - u1] | near[base + min(j + u1, uWm1)]
                t1[k] = m1
                t2[k] = m1 | near[base + max(j, u2) - u2] | near[base + min(j + u2, uWm1)]
            for j in range(J0, J1 + u1):
                k = base + j
                m1 = near[k] | near[k - u1] | near[k + u1]
                t1[k] = m1
                t2[k] = m1 | near[k - u2] | near[k + u2]
            for j in range(max(J1 + u1, uC0), uC1 + u1):
                k = base + j
                m1 = near[k] | near[base + max(j, u1) - u1] | near[base + min(j + u1, uWm1)]
                t1[k] = m1
                t2[k] = m1 | near[base + max(j, u2) - u2] | near[base + min(j + u2, uWm1)]
        for i in range(R0, R1 + 1):
            b = np.uint64(i) * uW
            bm1, bp1 = np.uint64(max(i - 1, R0)) * uW, np.uint64(min(i + 1, R1)) * uW
            bm2, bp2 = np.uint64(max(i - 2, R0)) * uW, np.uint64(min(i + 2, R1)) * uW
            for j in range(uC0, uC1 + u1):
                a1[b + j] = t1[b + j] | t1[bm1 + j] | t1[bp1 + j]
                a2[b + j] = t2[b + j] | t2[bm1 + j] | t2[bp1 + j] | t2[bm2 + j] | t2[bp2 + j]
        # the unit normal and the distance term's flux: every pixel of the box's interior
        # without a branch (vectorised; a value outside a2 is never read), then the array's
        # outer rows and columns where a2 reaches them, with one-sided differences
        uI0, uI1 = np.uint64(max(C0, 1)), np.uint64(min(C1, W - 2))
        for i in range(max(R0, 1), min(R1, H - 2) + 1):
            base = np.uint64(i) * uW
            for j in range(uI0, uI1 + u1):
                k = base + j
                dx = half * (pf[k + u1] - pf[k - u1])
                dy = half * (pf[k + uW] - pf[k - uW])
                s2 = dx * dx + dy * dy
                s = np.sqrt(s2)
                inv = one / (s + tiny)
                nx[k] = dx * inv
                ny[k] = dy * inv
                # the polynomial on every lane, then a select: evaluated under the branch, its
                # coefficients' loads become masked gathers in every vector; s2 is capped so
                # that the discarded lanes stay finite
                poly = _poly(min(s2, one), dps_c)
                dps = poly if s < one else one - inv  # s + tiny == s for s >= 1
                qx[k] = (dps - one) * dx
                qy[k] = (dps - one) * dy
        for i in range(R0, R1 + 1):
            base = np.uint64(i) * uW
            if i == 0 or i == H - 1:
                for j in range(uC0, uC1 + u1):
                    if a2[base + j]:
                        _derivatives_at(pf, nx, ny, qx, qy, base + j, i, j, H, uW, dps_c)
            else:
                if C0 == 0 and a2[base]:
                    _derivatives_at(pf, nx, ny, qx, qy, base, i, u0, H, uW, dps_c)
                if C1 == W - 1 and a2[base + uWm1]:
                    _derivatives_at(pf, nx, ny, qx, qy, base + uWm1, i, uWm1, H, uW, dps_c)
        # the update on a1, as a select over the box's interior (vectorised)
        for i in range(max(R0, 1), min(R1, H - 2) + 1):
            base = np.uint64(i) * uW
            for j in range(uI0, uI1 + u1):
                k = base + j
                p = pf[k]
                curv = half * (nx[k + u1] - nx[k - u1]) + half * (ny[k + uW] - ny[k - uW])
                dist = (
                    half * (qx[k + u1] - qx[k - u1])
                    + half * (qy[k + uW] - qy[k - uW])
                    + (pf[k + uW] + pf[k - uW] + pf[k + u1] + pf[k - u1] - np.float32(4.0) * p)
                )
                r = p * inv_eps
                de = _poly(r * r, de_c)
                edge = de * (gxf[k] * nx[k] + gyf[k] * ny[k] + gf[k] * curv)
                near_zero = p + dt * (mu * dist + lam * edge + a * gf[k] * de)
                far = p + dt * mu * dist
                v = near_zero if abs(p) <= eps else far
                new[k] = v if a1[k] else p
        for i in range(max(R0, 1), min(R1, H - 2) + 1):
            base = np.uint64(i) * uW
            for j in range(uI0, uI1 + u1):
                k = base + j
                pf[k] = new[k]
        r0, r1, c0, c1 = R0, R1, C0, C1
    _mirror_border(phi)
    return done, n_checks, refining


@dataclass(frozen=True)
class EvolveIter:
    """One stopping-rule check of :func:`evolve`, as ``iter_callback`` receives it."""

    iteration: int
    area_px: int


@dataclass(frozen=True)
class LevelSetResult:
    """Outcome of :func:`evolve`: the final phi (float32), iterations run, convergence flag."""

    phi: NDArray[np.float32]
    iterations: int
    converged: bool


def evolve(
    phi0: np.ndarray,
    em: EdgeMap,
    cfg: LevelSetConfig,
    warm: bool = False,
    iter_callback: Callable[[EvolveIter], None] | None = None,
) -> LevelSetResult:
    """Evolve ``phi0`` (not modified) on the edge map ``em`` until the area is stable.

    Parameters
    ----------
    phi0 : (H, W) float
        Initial level-set function, inside = phi < 0 (``box_step`` for a cold start, the
        previous frame's phi moved by the target's displacement for a warm start).
    em : EdgeMap
        From :func:`edge_map` of the same region.
    cfg : LevelSetConfig
        Parameters.
    warm : bool
        Use the warm iteration cap.
    iter_callback : callable, optional
        Called with an :class:`EvolveIter` for every stopping-rule check the evolution made
        (every ``check_every`` iterations: the iteration and the inside area then), in order,
        once the evolution has returned: the iterations run in one compiled call, which keeps
        no Python in its loop, so the history is handed over afterwards. It sees what a
        callback at each check would see, and cannot stop the evolution.
    """
    if phi0.shape != em.g.shape:
        raise ValueError(
            f"phi0 {phi0.shape} and the edge map {em.g.shape} must have the same shape"
        )
    if min(phi0.shape) < 5:
        raise ValueError(f"the level-set region must be at least 5x5 px; got {phi0.shape}")
    phi = np.ascontiguousarray(phi0, dtype=np.float32).copy()
    dps_c, de_c = _polynomials(float(cfg.dirac_width))
    cap = cfg.max_iterations_warm if warm else cfg.max_iterations_cold
    mu, lam = np.float32(cfg.distance_weight), np.float32(cfg.length_weight)
    eps, dt, band = np.float32(cfg.dirac_width), np.float32(cfg.timestep), np.float32(cfg.band_px)
    areas = np.zeros(cap // cfg.check_every + 2, np.int64)
    alpha = np.float32(cfg.area_weight_warm if warm else cfg.area_weight)
    it, n_checks, refined = _band_iterations(
        phi,
        em.g,
        em.gx,
        em.gy,
        cap,
        mu,
        lam,
        alpha,
        eps,
        dt,
        band,
        dps_c,
        de_c,
        cfg.check_every,
        cfg.stop_window // cfg.check_every,
        cfg.stop_tolerance,
        areas,
        cfg.refine_iterations,
    )
    converged = it < cap and n_checks > 0 and areas[n_checks - 1] > 0
    if iter_callback is not None:
        for k in range(n_checks):
            iter_callback(EvolveIter((k + 1) * cfg.check_every, int(areas[k])))
    if refined:
        it += cfg.refine_iterations
    return LevelSetResult(phi, it, converged)


@cache
def warm_up() -> None:
    """Compile (first run) or load from numba's cache (later runs) the level-set kernel by evolving
    a 16x16 region once, so that a tracker's first frame does not pay for it: a cold compile takes
    seconds and would otherwise be counted as tracking time (``fps_tracking``). Runs once per
    process."""
    em = edge_map(np.zeros((16, 16), np.uint8), LevelSetConfig())  # also compiles _diff_pair
    evolve(box_step((16, 16), (4.0, 4.0, 8.0, 8.0), 2.0), em, LevelSetConfig())
