"""The IR contour stage of the dual tracker: a DRLSE level set on a region around the target.

:func:`extract_contour` crops the IR frame around the expected box, starts the level set
either cold (a binary step on the expected box enlarged ``cold_start_scale`` times; alpha > 0
shrinks it onto the target) or warm (the previous frame's level-set function moved by the
target's displacement, clipped to +-c0), evolves it (``pipeline.stages.levelset``), and
reads the result: connected components of ``phi < 0``; the target is the component with
most pixels inside the expected box, together with the smaller parts (limbs cut off by the
length term) that lie mostly inside it. Its box is measured at sub-pixel precision from
the zero crossings of phi. Several separate components mean several objects
(``ContourResult.components`` lists them all).

Failures are results, not exceptions (``ContourResult.reason``): ``no-component`` (nothing
overlaps the expected box), ``leak`` (the selection touches the region border),
``collapse`` (its box is under ``min_area_fraction`` of the expected box), ``too-large``
(over ``max_area_ratio`` of it, e.g. merged with a warm neighbour), ``shape-change`` (width
or height off by more than ``max_dimension_ratio``) and ``low-contrast``
(its mean IR differs from the surrounding ring by under ``min_contrast`` grey levels,
thermal crossover).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from functools import cache

import cv2
import numba
import numpy as np

from pipeline.params import Section, param
from pipeline.stages import levelset
from pipeline.stages._labels import components, counts_in_rect, select_labels
from pipeline.stages._labels import warm_up as labels_warm_up
from pipeline.stages.levelset import LevelSetConfig, box_step, edge_map, evolve
from pipeline.types import BBox, Points


@dataclass(frozen=True)
class ContourConfig(Section):
    """Region, initialisation and failure tests of the contour stage.

    Parameters
    ----------
    roi_margin_px : float
        The region is the expected box grown per side by max(this, ``roi_margin_fraction``
        x its size), px, >= 4; default 10. Keeps the Neumann border away from the contour.
    roi_margin_fraction : float
        See ``roi_margin_px``, in [0, 2]; default 0.35.
    cold_start_scale : float
        A cold start begins from the expected box times this, in [1, 2]; default 1.35
        (docs/algorithms.md §1.6: 1.3-1.5).
    warm_start : bool
        Beyond the paper: start from the previous frame's level-set function moved by the
        target's displacement when there is one; default True.
    warm_dilate_px : float
        A warm start begins this far outside the previous contour (a signed distance of
        its inside, offset outward), so the balloon term can shrink it back onto the edges
        and a part lost in one frame can be regained in the next, px, >= 0; default 3
        (docs/algorithms.md §1.6 suggests 4-8 px with alpha 1.5).
    min_area_fraction : float
        Collapse below this share of the expected box area, in (0, 1); default 0.3.
    max_area_ratio : float
        Too large above this multiple of the expected box area, > 1; default 2.2.
    min_contrast : float
        Low contrast when the target's mean IR differs from the ring around it by less
        than this, grey levels, >= 0; default 6. Increasing it gives up on the IR channel
        earlier during thermal crossover.
    part_fraction : float
        A further component joins the target when this share of its box lies inside the
        expected box (grown 15 %), in (0, 1]; default 0.6.
    max_dimension_ratio : float
        ``shape-change`` when the contour box's width or height differs from the expected
        box's by more than this factor, > 1; default 1.45. (A contour that kept half a
        body can have a plausible area and the wrong shape.)
    closing_fraction : float
        Beyond the paper: a grey-level closing (elliptical element of this share of the
        target's width) is applied to the IR region before the edge map, so thin parts
        (legs, arms) merge into the body instead of being cut by the length term;
        in [0, 1], default 0.25, 0 disables it. Increasing it fills more of a thin
        target and starts to bridge a gap to a neighbour.
    checks : bool
        Beyond the paper: the tracker takes a contour as a measurement only when it passes
        the failure tests above (no leak, collapse, growth, change of shape or loss of
        contrast), and a contour much smaller than the target means something stands in
        front; default True (False takes any contour, as the paper does).
    trust_faded : bool
        The tracker takes a contour that failed only for low contrast (thermal crossover);
        default False (True is the paper's, which has no contrast test).
    start_at : str
        Where the tracker starts the level set: ``cues`` (default: the filter's detection
        when it is confident, the mean shift when its colour match is good, else the
        prediction) or ``meanshift`` (the paper's step 3: the mean-shift position).
    retry_empty_frames : int
        Beyond the paper: a target without a level set to warm-start from whose last ``n``
        cold starts found nothing (``no-component``), ``n`` over ``retry_after_empty``, is
        given the next one ``2 ** (n - retry_after_empty)`` frames after the last, at most
        this many, while the filter detects it confidently (``not-run`` on the frames between,
        which the decision reads as a contour that found nothing); a target the filter is
        unsure of, or that is missing, gets one on every frame. Frames, >= 1; default 8; 1
        runs a cold start on every frame (the paper's). A target whose IR has no edge the
        balloon can stop at (a low-contrast vehicle, a body at thermal crossover) otherwise
        costs a cold start of 80-200 iterations a frame; larger values save more and find an
        IR contour that appears later up to this many frames late.
    retry_after_empty : int
        The cold starts running that may find nothing before ``retry_empty_frames`` spaces
        them, >= 1; default 3. On the development range, after one to three empty cold starts
        the next one found something on 8-19 % of frames, after more on 2-5 %.
    warm_part : bool
        Beyond the paper: where the first frame's contour collapsed to a part inside the given
        box with contrast (a cyclist's rider without the cold bicycle, a torso without cold
        legs), the tracker takes that part as what the IR shows of the target: a later contour
        that collapses to the part's size (its size tests against the part, scaled with the
        target) is ``part``, and the target is not partly hidden for it (its status stays
        ``tracking`` and its models learn; the box is measured by the other cues, as after any
        collapse). Default True; False calls every such frame a partial occlusion unless the
        colour matches the whole target (``decider.whole_colour_rho``).
    warm_part_min_fraction : float
        The smallest share of the given box's area such a part may cover, in (0, 1); default
        0.08. A smaller part (a warm head) is not told from a target mostly hidden at the
        start.
    """

    section = "contour"

    roi_margin_px: float = param(10.0, ge=4)
    roi_margin_fraction: float = param(0.35, ge=0, le=2)
    cold_start_scale: float = param(1.35, ge=1, le=2)
    warm_start: bool = True
    warm_dilate_px: float = param(3.0, ge=0)
    min_area_fraction: float = param(0.3, gt=0, lt=1)
    max_area_ratio: float = param(2.2, gt=1)
    min_contrast: float = param(6.0, ge=0)
    part_fraction: float = param(0.6, gt=0, le=1)
    max_dimension_ratio: float = param(1.45, gt=1)
    closing_fraction: float = param(0.25, ge=0, le=1)
    checks: bool = True
    trust_faded: bool = False
    start_at: str = param("cues", choices=("cues", "meanshift"))
    retry_empty_frames: int = param(8, ge=1)
    retry_after_empty: int = param(3, ge=1)
    warm_part: bool = True
    warm_part_min_fraction: float = param(0.08, gt=0, lt=1)


@dataclass(frozen=True)
class LevelSetMemory:
    """The level-set function of a frame and where its region lay (frame px of its corner);
    a 1 x 1 ``phi`` (:meth:`empty`) means no level set ran."""

    phi: np.ndarray
    origin: tuple[int, int]

    @classmethod
    def empty(cls, origin: tuple[int, int] = (0, 0)) -> LevelSetMemory:
        """The memory of a frame without a level set: nothing to warm-start from."""
        return cls(np.zeros((1, 1), np.float32), origin)

    @property
    def warm(self) -> bool:
        """Whether it holds a level set a later frame can warm-start from."""
        return self.phi.size > 1


class ContourReason(enum.StrEnum):
    """Why a contour is or is not a measurement (``ContourResult.reason``; its value is what
    targets.csv says)."""

    OK = "ok"
    NO_COMPONENT = "no-component"  # nothing overlaps the expected box
    LEAK = "leak"  # the selection touches the region's border
    COLLAPSE = "collapse"  # under ``min_area_fraction`` of the expected box
    TOO_LARGE = "too-large"  # over ``max_area_ratio`` of it (merged with a warm neighbour)
    SHAPE_CHANGE = "shape-change"  # width or height off by more than ``max_dimension_ratio``
    LOW_CONTRAST = (
        "low-contrast"  # its IR differs from the ring around by under ``min_contrast`` (crossover)
    )
    NOT_RUN = "not-run"  # no level set this frame: its cold starts keep finding nothing


@dataclass(frozen=True)
class ContourResult:
    """Outcome of :func:`extract_contour` (boxes and contours in frame px)."""

    ok: bool
    reason: ContourReason
    box: BBox | None
    contour: tuple[Points, ...]
    iterations: int
    contrast: float
    memory: LevelSetMemory
    components: tuple[BBox, ...] = field(default_factory=tuple)
    warm: bool = False
    at_border: tuple[bool, bool] = (
        False,
        False,
    )  # the selection reaches the frame's border along x / y
    part: bool = False  # a collapse the size of the target's known warm part (the tracker's)


def region(
    expected: BBox, cfg: ContourConfig, width: int, height: int
) -> tuple[int, int, int, int]:
    """Integer ``(x0, y0, x1, y1)`` of the level-set region around ``expected``, clipped."""
    mx = max(cfg.roi_margin_px, cfg.roi_margin_fraction * expected.w)
    my = max(cfg.roi_margin_px, cfg.roi_margin_fraction * expected.h)
    x0 = max(int(np.floor(expected.x - mx)), 0)
    y0 = max(int(np.floor(expected.y - my)), 0)
    x1 = min(int(np.ceil(expected.x2 + mx)), width)
    y1 = min(int(np.ceil(expected.y2 + my)), height)
    return x0, y0, max(x1, x0 + 1), max(y1, y0 + 1)


def warm_phi(
    memory: LevelSetMemory,
    shift: tuple[float, float],
    origin: tuple[int, int],
    shape: tuple[int, int],
    c0: float,
    dilate_px: float = 0.0,
) -> np.ndarray:
    """The previous phi moved by ``shift`` (frame px) into a region at ``origin``, its zero level
    moved ``dilate_px`` outward (through a signed distance of its inside), clipped to +-c0."""
    tx = origin[0] - memory.origin[0] - shift[0]
    ty = origin[1] - memory.origin[1] - shift[1]
    M = np.array([[1.0, 0.0, tx], [0.0, 1.0, ty]], np.float32)
    phi = cv2.warpAffine(
        memory.phi,
        M,
        (shape[1], shape[0]),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(c0),
    )
    if dilate_px > 0:  # distance outside the previous inside, offset outward; flat -c0 inside
        d_out = cv2.distanceTransform(_outside(phi), cv2.DIST_L2, 3)
        return _dilated(phi, d_out, np.float32(dilate_px), np.float32(c0))
    return np.clip(phi, -c0, c0).astype(np.float32)


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")  # no fastmath
def _outside(phi):  # pragma: no cover (compiled)
    """uint8 1 where ``phi >= 0`` (not inside), 0 inside."""
    H, W = phi.shape
    out = np.empty((H, W), np.uint8)
    for i in range(H):
        for j in range(W):
            out[i, j] = 0 if phi[i, j] < 0 else 1
    return out


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")  # no fastmath
def _dilated(phi, d_out, dilate, c0):  # pragma: no cover (compiled)
    """``-c0`` inside (``phi < 0``), ``d_out - dilate`` outside, clipped to ``+-c0`` (float32, as
    numpy's ``where`` and ``clip`` give it)."""
    H, W = phi.shape
    out = np.empty((H, W), np.float32)
    for i in range(H):
        for j in range(W):
            v = -c0 if phi[i, j] < 0 else d_out[i, j] - dilate
            out[i, j] = min(max(v, -c0), c0)
    return out


@numba.njit(
    cache=True, boundscheck=False, nogil=True, error_model="numpy"
)  # no fastmath: the same float32 arithmetic as numpy
def _reach(phi, mask, fixed, lo, hi, step, along_rows):  # pragma: no cover (compiled)
    """Farthest fraction of a pixel beyond the inside pixel centres of line ``fixed`` (a column
    when ``along_rows``, else a row) where phi crosses 0 towards ``fixed + step``; 0.5 past the
    array edge."""
    n = phi.shape[1] if along_rows else phi.shape[0]
    if fixed + step < 0 or fixed + step >= n:
        return 0.5
    best = np.float32(-1.0)
    for k in range(lo, hi):
        if along_rows:
            if not mask[k, fixed]:
                continue
            inside, outside = phi[k, fixed], phi[k, fixed + step]
        else:
            if not mask[fixed, k]:
                continue
            inside, outside = phi[fixed, k], phi[fixed + step, k]
        d = outside - inside
        if d > 0:
            f = -inside / d
            f = min(max(f, np.float32(0.0)), np.float32(1.0))
        else:
            f = np.float32(0.5)
        best = max(best, f)
    return 0.5 if best < 0 else float(best)


def _ring_contrast(roi: np.ndarray, sel_u8: np.ndarray) -> float:
    """Mean IR of the selection minus the mean of the ring around it (its 7x7 dilation minus
    itself), 0 without a ring, in one compiled pass. The sums are exact integers, each mean a
    float32 quotient: numpy's float32 means of the same pixels wherever their sums stay below 2**24
    (tested), i.e. any region under 65 000 px; above that these are the more exact ones."""
    return _ring_contrast_kernel(np.ascontiguousarray(roi), sel_u8)


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")  # no fastmath
def _ring_contrast_kernel(roi, sel):  # pragma: no cover (compiled)
    H, W = sel.shape
    # the 7x7 dilation by running counts: along rows, then the rows' results down the columns
    near = np.zeros((H, W), np.int32)
    for i in range(H):
        c = 0
        for j in range(min(3, W)):
            c += sel[i, j]
        for j in range(W):
            if j + 3 < W:
                c += sel[i, j + 3]
            if j - 4 >= 0:
                c -= sel[i, j - 4]
            near[i, j] = c > 0
    col = np.zeros(W, np.int32)
    for i in range(min(3, H)):
        for j in range(W):
            col[j] += near[i, j]
    s_in = n_in = s_ring = n_ring = 0
    for i in range(H):
        if i + 3 < H:
            for j in range(W):
                col[j] += near[i + 3, j]
        if i - 4 >= 0:
            for j in range(W):
                col[j] -= near[i - 4, j]
        for j in range(W):
            if sel[i, j]:
                s_in += roi[i, j]
                n_in += 1
            elif col[j] > 0:
                s_ring += roi[i, j]
                n_ring += 1
    if n_ring == 0 or n_in == 0:
        return 0.0
    return float(np.float32(s_in) / np.float32(n_in) - np.float32(s_ring) / np.float32(n_ring))


def _subpixel_box(phi: np.ndarray, mask: np.ndarray) -> tuple[float, float, float, float]:
    """Box (x0, y0, x1, y1) of ``mask`` with each edge at the farthest interpolated zero crossing
    of phi along the rows (left, right) or columns (top, bottom) that reach the mask's extreme."""
    m = mask.astype(np.uint8)
    return _subpixel_edges(phi, m, *cv2.boundingRect(m))


def _subpixel_edges(
    phi: np.ndarray, m: np.ndarray, c0: int, r0: int, bw: int, bh: int
) -> tuple[float, float, float, float]:
    """:func:`_subpixel_box` of the uint8 mask ``m`` whose bounding rectangle is given."""
    c1, r1 = c0 + bw - 1, r0 + bh - 1
    left = c0 + 0.5 - _reach(phi, m, c0, r0, r1 + 1, -1, True)
    right = c1 + 0.5 + _reach(phi, m, c1, r0, r1 + 1, 1, True)
    top = r0 + 0.5 - _reach(phi, m, r0, c0, c1 + 1, -1, False)
    bottom = r1 + 0.5 + _reach(phi, m, r1, c0, c1 + 1, 1, False)
    return left, top, right, bottom


def size_reason(box: BBox, expected: BBox, cfg: ContourConfig) -> ContourReason:
    """The size tests of a contour's ``box`` against the ``expected`` one: ``collapse`` (under
    ``min_area_fraction`` of its area), ``too-large`` (over ``max_area_ratio``),
    ``shape-change`` (a side off by more than ``max_dimension_ratio``), else ``ok``.

    Examples
    --------
    >>> cfg = ContourConfig()
    >>> size_reason(BBox(0, 0, 12, 18), BBox(0, 0, 36, 36), cfg).value
    'collapse'
    >>> size_reason(BBox(0, 0, 11, 16), BBox(0, 0, 12, 18), cfg).value
    'ok'
    """
    if box.area < cfg.min_area_fraction * expected.area:
        return ContourReason.COLLAPSE
    if box.area > cfg.max_area_ratio * expected.area:
        return ContourReason.TOO_LARGE
    r = cfg.max_dimension_ratio
    if not (1 / r <= box.w / expected.w <= r and 1 / r <= box.h / expected.h <= r):
        return ContourReason.SHAPE_CHANGE
    return ContourReason.OK


def extract_contour(
    ir: np.ndarray,
    expected: BBox,
    cfg: ContourConfig,
    ls_cfg: LevelSetConfig,
    memory: LevelSetMemory | None = None,
    shift: tuple[float, float] = (0.0, 0.0),
    cold_init: BBox | None = None,
    part_width: float | None = None,
) -> ContourResult:
    """Level-set contour of the target expected at ``expected`` (frame px) in the IR frame ``ir``.

    Parameters
    ----------
    ir : (H, W) uint8
        Infrared frame.
    expected : BBox
        Where the target should be (mean-shift position y1 with the current size).
    cfg, ls_cfg : ContourConfig, LevelSetConfig
        Parameters.
    memory : LevelSetMemory, optional
        Previous frame's level set (warm start when ``cfg.warm_start``).
    shift : (dx, dy)
        Displacement of the target since ``memory``, px.
    cold_init : BBox, optional
        Initial contour for a cold start (default: ``expected`` x ``cold_start_scale``),
        e.g. the union of two merged targets.
    part_width : float, optional
        Width of one target, for the closing (default: ``expected.w``); give it when
        ``expected`` spans several targets, so the gap between them is not closed.
    """
    if ir.ndim != 2:
        raise ValueError(f"ir must be (H, W); got shape {ir.shape}")
    H, W = ir.shape
    x0, y0, x1, y1 = region(expected, cfg, W, H)
    roi = ir[y0:y1, x0:x1]
    empty_mem = LevelSetMemory.empty((x0, y0))
    if roi.shape[0] < 8 or roi.shape[1] < 8:
        return ContourResult(False, ContourReason.NO_COMPONENT, None, (), 0, 0.0, empty_mem)
    k = round(cfg.closing_fraction * (part_width or expected.w)) | 1
    if cfg.closing_fraction > 0 and k >= 3:
        roi = cv2.morphologyEx(
            roi, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
        )
    em = edge_map(roi, ls_cfg)
    warm = cfg.warm_start and memory is not None and memory.warm
    if warm:
        # type: ignore[arg-type]
        phi0 = warm_phi(memory, shift, (x0, y0), roi.shape, ls_cfg.step_height, cfg.warm_dilate_px)
        if not (phi0 < 0).any():
            warm = False
    if not warm:
        init = (cold_init or expected.scaled(cfg.cold_start_scale)).shifted(-x0, -y0)
        phi0 = box_step(roi.shape, init.as_tuple(), ls_cfg.step_height)
    res = evolve(phi0, em, ls_cfg, warm=warm)
    phi = res.phi
    mem = LevelSetMemory(phi, (x0, y0))
    mask = (phi < 0).astype(np.uint8)
    n, labels, stats, _ = components(mask)
    comps = [
        BBox(
            float(stats[i, 0] + x0),
            float(stats[i, 1] + y0),
            float(stats[i, 2]),
            float(stats[i, 3]),
        )
        for i in range(1, n)
        if stats[i, 4] >= 4
    ]
    if n <= 1:
        return ContourResult(
            False,
            ContourReason.NO_COMPONENT,
            None,
            (),
            res.iterations,
            0.0,
            mem,
            tuple(comps),
            warm,
        )
    ex = expected.shifted(-x0, -y0)
    # the labels' pixels inside the expected box (numpy's slicing: the lower ends at 0)
    inside_counts = counts_in_rect(
        labels,
        n,
        max(int(ex.x), 0),
        max(int(ex.y), 0),
        max(int(np.ceil(ex.x2)), 0),
        max(int(np.ceil(ex.y2)), 0),
    )
    best = int(np.argmax(inside_counts))
    if inside_counts[best] == 0:
        return ContourResult(
            False,
            ContourReason.NO_COMPONENT,
            None,
            (),
            res.iterations,
            0.0,
            mem,
            tuple(comps),
            warm,
        )
    chosen = np.zeros(n, np.bool_)
    chosen[best] = True
    grown = ex.scaled(1.15)
    for i in range(1, n):
        if i == best or stats[i, 4] < 4:
            continue
        b = BBox(float(stats[i, 0]), float(stats[i, 1]), float(stats[i, 2]), float(stats[i, 3]))
        if b.intersect(grown).area >= cfg.part_fraction * b.area:
            chosen[i] = True
    sel_u8, bx, by, bw, bh = select_labels(labels, chosen)
    h, w = mask.shape
    touches = by <= 1 or bx <= 1 or by + bh - 1 >= h - 2 or bx + bw - 1 >= w - 2
    at_border = (
        (bx <= 1 and x0 == 0) or (bx + bw - 1 >= w - 2 and x1 == W),
        (by <= 1 and y0 == 0) or (by + bh - 1 >= h - 2 and y1 == H),
    )
    left, top, right, bottom = _subpixel_edges(phi, sel_u8, bx, by, bw, bh)
    box = BBox(left + x0, top + y0, right - left, bottom - top)
    contrast = _ring_contrast(roi, sel_u8)
    cs, _ = cv2.findContours(sel_u8, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    contour = tuple(
        c.reshape(-1, 2).astype(np.float64) + np.array([x0 + 0.5, y0 + 0.5])
        for c in cs
        if len(c) >= 3
    )
    reason = ContourReason.OK
    if touches:
        reason = ContourReason.LEAK
    else:
        reason = size_reason(box, expected, cfg)
    if reason == ContourReason.OK and abs(contrast) < cfg.min_contrast:
        reason = ContourReason.LOW_CONTRAST
    return ContourResult(
        reason == ContourReason.OK,
        reason,
        box,
        contour,
        res.iterations,
        contrast,
        mem,
        tuple(comps),
        warm,
        at_border,
    )


@cache
def warm_up() -> None:
    """Compile or load the contour stage's numba kernels (the level set's, :func:`_reach` and the
    ring contrast's) once per process, so that a tracker's first timed frame does not pay for it.
    """
    levelset.warm_up()
    labels_warm_up()
    phi = np.full((6, 6), 2.0, np.float32)
    phi[2:4, 2:4] = -2.0
    _subpixel_box(phi, phi < 0)
    _ring_contrast(np.zeros((6, 6), np.uint8), (phi < 0).astype(np.uint8))
    _dilated(phi, np.abs(phi), np.float32(1.0), np.float32(2.0))
    _outside(phi)
