"""The dual tracker's updates after a decision: size, colour model, correlation filter, motion."""

from __future__ import annotations

import math

import numpy as np

from pipeline.config import PipelineConfig
from pipeline.stages import appearance as app
from pipeline.stages import kalman
from pipeline.stages.contour import ContourResult
from pipeline.stages.histogram import bhattacharyya, ellipse_model
from pipeline.stages.model_update import UpdateDecision, selective_update, should_update_model
from pipeline.stages.motion import coast_start, stop
from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.cues import AppearanceCue, ColourStep
from pipeline.trackers.dual.decide import REDETECTED, Case, Decision
from pipeline.types import BBox, TargetStatus


def scale_update(
    h: tuple[float, float], h_contour: tuple[float, float], rate: float
) -> tuple[float, float]:
    """Eq. 7: ``h_new = (1 - a) h + a h_contour`` for width and height."""
    return ((1 - rate) * h[0] + rate * h_contour[0], (1 - rate) * h[1] + rate * h_contour[1])


def fused_size(
    size: tuple[float, float],
    app_size: tuple[float, float],
    decision: Decision,
    contour: ContourResult | None,
    cue: AppearanceCue | None,
    dcfg: DualConfig,
    min_contrast: float,
    extent: BBox | None = None,
    extent_ratio: float = 1.0,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The size after this frame and the filter's own size: ``(size, app_size)``.

    The filter's size follows its scale estimate alone, when it is confident. The size follows the
    same change, then eq. 7 towards the contour's size when the contour is clean and clearly
    contrasted; with a filter, only a contour within ``scale_agree_ratio`` of the filter's size
    counts, and the size stays within that ratio of it. A contour that covers part of the target,
    or leaks into a neighbour, so cannot drag the size: it is measured against a size it never
    entered. With a filter, the colour ``extent`` (when measured) moves width and height each at
    eq. 7's rate towards it where it is larger than the filter's size (a smaller one means part of
    the target has the background's colours), and the size may exceed the filter's by
    ``extent_ratio`` per axis (1: by ``scale_agree_ratio`` only)."""
    if not decision.measured:
        return size, app_size
    filt = cue is not None and dcfg.appearance_cue
    confident = filt and cue.psr >= dcfg.psr_confident  # type: ignore[union-attr]
    base = size
    if confident:
        f = cue.scale_factor  # type: ignore[union-attr]
        base, app_size = (size[0] * f, size[1] * f), (app_size[0] * f, app_size[1] * f)
    r = dcfg.scale_agree_ratio
    if (
        decision.contour_scale
        and contour is not None
        and contour.box is not None
        and abs(contour.contrast) >= 2 * min_contrast
    ):
        cw, ch = contour.box.w, contour.box.h
        if not filt or (1 / r <= cw / app_size[0] <= r and 1 / r <= ch / app_size[1] <= r):
            base = scale_update(base, (cw, ch), dcfg.scale_rate)
    if extent is not None and filt:
        # the colour shows where a target is wider or taller than the filter's size; a smaller
        # extent only means that part of it has the background's colours
        base = scale_update(
            base, (max(extent.w, app_size[0]), max(extent.h, app_size[1])), dcfg.scale_rate
        )
    if filt:
        up = max(r, extent_ratio)
        base = (
            min(max(base[0], app_size[0] / r), app_size[0] * up),
            min(max(base[1], app_size[1] / r), app_size[1] * up),
        )
    return base, app_size


def update_colour_model(
    q: np.ndarray,
    bins: np.ndarray | None,
    roi0: tuple[int, int],
    box: BBox,
    learn: bool,
    measured: bool,
    cfg: PipelineConfig,
) -> tuple[np.ndarray, UpdateDecision, float]:
    """Eq. 8-9 with the histogram at the new box (the gate: ``pipeline.stages.model_update``): (q,
    decision, rho2)."""
    mu_cfg = cfg.model_update
    if measured and bins is not None and not learn and mu_cfg.enabled:
        return q, UpdateDecision(False, "unconfirmed"), float("nan")
    if not measured or bins is None or not learn:
        return (
            q,
            should_update_model(0.0, not measured, bins is not None, learn, mu_cfg),
            float("nan"),
        )
    p, _, mass = ellipse_model(
        bins, box.cx - roi0[0], box.cy - roi0[1], box.w / 2, box.h / 2, q.size
    )
    if mass < cfg.meanshift.min_mass_fraction:
        return q, UpdateDecision(False, "window-cut-by-border"), float("nan")
    rho2 = bhattacharyya(p, q)
    decision = should_update_model(rho2, False, True, True, mu_cfg)
    return (selective_update(q, p, mu_cfg) if decision.update else q), decision, rho2


def update_appearance(
    model: app.AppearanceModel | None,
    frames_vis,
    frames_ir,
    box: BBox,
    decision: Decision,
    colour: UpdateDecision,
    informative: bool,
    acfg: app.AppearanceConfig,
    frame: int,
) -> app.AppearanceModel | None:
    """The filter blended with this frame when the decision lets the models learn and the colour's
    selective update did not freeze for a change of appearance (eq. 8-9 gates the filter's learning
    rate); on every ``update_every_frames``-th frame only, at the rate compounded over them."""
    if (
        model is None
        or not decision.measured
        or not decision.learn
        or frame % acfg.update_every_frames
    ):
        return model
    if informative and not colour.update and colour.reason in ("rho-low", "occluded"):
        return model
    k = acfg.update_every_frames
    ks = acfg.scale_every_frames  # the scale filter learns on the frames it estimates on
    scale_rate = 1 - (1 - acfg.scale_learning_rate) ** math.lcm(k, ks) if frame % ks == 0 else 0.0
    return app.update(
        model,
        frames_vis,
        frames_ir,
        box,
        acfg,
        rate=1 - (1 - acfg.learning_rate) ** k,
        scale_rate=scale_rate,
    )


def motion_update(
    cs: ColourStep,
    decision: Decision,
    out: BBox,
    frame: int,
    dcfg: DualConfig,
    kcfg,
    history: tuple,
) -> tuple[kalman.GaussianState, tuple, BBox]:
    """The Kalman filter after this frame: corrected by the measurement (its noise scaled per
    case), restarted at rest on a target found again after it was lost or by the widened search, or
    coasting (restarted at an occlusion's onset from a line through the recent clean measurements,
    stopped once lost). Returns the state, the history and the output box (moved to the restarted
    coast)."""
    t, prior = cs.t, cs.prior
    Hm, Rm = kalman.measurement_model(kcfg)
    if (
        decision.measured
        and decision.case == Case.REACQUIRED
        and (t.status == TargetStatus.LOST or decision.why == REDETECTED)
    ):
        # found again after it was given up, or by the widened search: the jump from where it was
        # believed to be is not its motion; the filter restarts at the measurement, at rest
        kf = kalman.init_state(out, kcfg)
        return kf, ((float(frame), out.cx, out.cy, out.w, out.h),), out
    if decision.measured:
        kf = kalman.correct(
            prior, kalman.box_measurement(out), Hm, Rm * max(decision.noise, 1e-6), kcfg
        ).state
        if (
            decision.case in (Case.CONTOUR, Case.APPEARANCE)
            and decision.status == TargetStatus.TRACKING
        ):
            history = (*history, (float(frame), out.cx, out.cy, out.w, out.h))[
                -dcfg.history_frames :
            ]
        return kf, history, out
    kf = prior
    if t.missing == 0:  # an occlusion starts: coast from the recent clean measurements
        restart = coast_start(
            t.history, prior, frame, dcfg.rewind_frames + dcfg.onset_frames, dcfg.onset_frames
        )
        if restart is not None:
            kf = restart
            ref = t.reference_size
            out = BBox.from_center(float(kf.x[0]), float(kf.x[1]), ref[0], ref[1])
    if (
        decision.status == TargetStatus.LOST
    ):  # a lost target stays where it was last believed to be
        kf = stop(kf)
    return kf, history, out
