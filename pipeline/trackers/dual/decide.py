"""The dual tracker's per-frame decision: which measurement a target gets, from which cue, and why.

Every cue of a frame is summed up in an :class:`Evidence` (plain values, so the decision is
testable case by case); :func:`decide` turns it into a :class:`Decision`: one of the named
:class:`Case` values, the measurement box, its noise for the Kalman update, the status, and
whether the models may learn from it. The same function serves the dual, the IR-only and
the visible-only modes: a cue the mode lacks is simply absent.

The rules, in order (``agree`` = centres within ``agree_fraction`` of the target's size):

Tracked last frame
    1. a clean contour that agrees with a confident filter detection: ``CONTOUR`` (both
       confirm it; the contour's size may be used);
    2. a confident filter detection, the contour failing or elsewhere: ``APPEARANCE`` (where
       the channels disagree, appearance decides);
    3. a clean contour, the filter unsure: ``CONTOUR`` unless a strong colour match says the
       target is elsewhere (then ``COLOUR``): a sharp IR contour carries the target through
       shadows and darkness, where its colour changes;
    4. a strong colour match: ``COLOUR`` (colour carries it through IR clutter and crossover);
    5. a contour lost to low contrast and a good colour match: ``COLOUR`` (thermal crossover);
    6. nothing: ``COAST`` on the motion prior, ``occluded-partial`` with some evidence,
       ``occluded-severe`` without.

Missing (hidden or lost)
    7. a filter detection at ``psr_reacquire`` near the prediction, or found farther by the
       re-detection search with a colour match (where colour is seen) at ``reacquire_rho``:
       ``REACQUIRED``;
    8. a clean contour near the prediction whose colour agrees (or no colour to ask):
       ``REACQUIRED``;
    9. a colour match at ``reacquire_rho`` near the prediction: ``REACQUIRED``;
    10. else ``COAST``, and ``LOST`` once missing for ``max_missing_frames`` or out of the frame.

With ``appearance_cue`` off there is no filter detection and rules 1, 2 and 7 never apply;
with ``contour_checks`` off every contour is clean (the paper).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from pipeline.stages.contour import ContourReason
from pipeline.tracker_config import DualConfig
from pipeline.types import BBox, TargetStatus

REDETECTED = "redetected"  # ``why`` of a target taken back by the widened or whole-frame search


class Case(enum.StrEnum):
    """Where a frame's measurement of a target came from (``targets.csv`` ``decision``, the .rrd
    timeline)."""

    CONTOUR = "contour"
    APPEARANCE = "appearance"
    COLOUR = "colour"
    REACQUIRED = "re-acquired"
    COAST = "coast"
    LOST = "lost"


@dataclass(frozen=True)
class Evidence:
    """What the cues found for one target in one frame (``nan`` / None where a cue is absent)."""

    measured_last: bool  # the target had a measurement in the previous frame
    missing: int  # frames since its last measurement
    prior: BBox  # where the motion model expects it
    ref_size: tuple[float, float]  # its usual size (w, h)
    colour_informative: bool
    rho_meanshift: float
    meanshift_box: BBox | None
    contour_box: BBox | None
    contour_ok: bool  # the contour passed its checks
    contour_reason: str  # a ContourReason, or "no-contour" without an IR frame
    rho_contour: float  # colour match at the contour's box
    appearance_box: BBox | None
    psr: float
    rho_appearance: float = float("nan")  # colour match at the filter's box
    support: tuple[float, float] = (
        float("nan"),
        float("nan"),
    )  # (visible, IR) PSR of each channel at the peak
    last: BBox | None = None  # the previous output box
    redetected: bool = False  # the filter's detection came from the re-detection search
    outside: bool = False  # the prediction has left the frame
    prior_std_px: tuple[float, float] = (
        0.0,
        0.0,
    )  # standard deviation of the predicted centre (x, y)

    @property
    def ref_area(self) -> float:
        return self.ref_size[0] * self.ref_size[1]


@dataclass(frozen=True)
class Decision:
    """The outcome: the case, the measurement (None when coasting), its noise scale, the status and
    why."""

    case: Case
    box: BBox | None
    noise: float
    status: TargetStatus
    why: str
    contour_scale: bool = False  # the contour's size may enter the size update
    learn: bool = False  # the models may learn from this frame
    stage: str = "kalman"  # the stage whose box was taken (targets.csv ``source``)

    @property
    def measured(self) -> bool:
        return self.box is not None


def agree(a: BBox, b: BBox, size: tuple[float, float], fraction: float) -> bool:
    """Centres of ``a`` and ``b`` within ``fraction`` of ``size`` on each axis."""
    return abs(a.cx - b.cx) <= fraction * size[0] and abs(a.cy - b.cy) <= fraction * size[1]


def near_prior(box: BBox, ev: Evidence, cfg: DualConfig) -> bool:
    """Within half the target's size of the prediction, plus ``reacquire_gate_px_per_frame`` per
    missing frame."""
    return near_prediction(box.center, ev.prior.center, ev.ref_size, ev.missing, cfg)


def near_prediction(
    center: tuple[float, float],
    predicted: tuple[float, float],
    ref_size: tuple[float, float],
    missing: int,
    cfg: DualConfig,
) -> bool:
    """:func:`near_prior` on plain values: ``center`` within half of ``ref_size`` of ``predicted``,
    plus ``reacquire_gate_px_per_frame`` per ``missing`` frame."""
    extra = cfg.reacquire_gate_px_per_frame * missing
    return (
        abs(center[0] - predicted[0]) <= 0.5 * ref_size[0] + extra
        and abs(center[1] - predicted[1]) <= 0.5 * ref_size[1] + extra
    )


def _good(x: float, threshold: float) -> bool:
    return not math.isnan(x) and x >= threshold


def decide(ev: Evidence, cfg: DualConfig) -> Decision:
    """The measurement of one target in one frame (the rules of the module doc, in order).

    Examples
    --------
    A clean contour where a confident filter detection is (rule 1), then the same frame with the
    contour leaking into a neighbour (rule 2):

    >>> from pipeline.trackers.dual import DualConfig, Evidence, decide
    >>> from pipeline.types import BBox
    >>> at = lambda cx: BBox.from_center(cx, 100, 20, 50)
    >>> ev = Evidence(measured_last=True, missing=0, prior=at(100), ref_size=(20, 50), colour_informative=True,
    ...               rho_meanshift=0.9, meanshift_box=at(101), contour_box=at(100.5), contour_ok=True,
    ...               contour_reason="ok", rho_contour=0.9, appearance_box=at(100.2), psr=15.0, rho_appearance=0.9)
    >>> d = decide(ev, DualConfig())
    >>> d.case.value, d.why, d.stage
    ('contour', 'contour-and-appearance', 'levelset')
    >>> import dataclasses
    >>> d = decide(dataclasses.replace(ev, contour_ok=False, contour_reason="leak"), DualConfig())
    >>> d.case.value, d.why, d.box == at(100.2)
    ('appearance', 'appearance-contour-leak', True)
    """
    appearance = ev.appearance_box is not None and cfg.appearance_cue
    confident = appearance and _good(ev.psr, cfg.psr_confident)
    can_learn = (appearance and _good(ev.psr, cfg.psr_update)) or not appearance
    contour = ev.contour_box
    contour_clean = contour is not None and (ev.contour_ok or not cfg.contour_checks)
    cut = (
        contour_clean
        and cfg.contour_checks
        and contour.area < cfg.partial_area_ratio * ev.ref_area
    )  # type: ignore[union-attr]
    colour_says_no = (
        ev.colour_informative
        and not math.isnan(ev.rho_contour)
        and ev.rho_contour < cfg.colour_min_rho
    )
    strong_colour = (
        ev.colour_informative
        and ev.meanshift_box is not None
        and cfg.colour_trust_rho < 1
        and _good(ev.rho_meanshift, cfg.colour_trust_rho)
    )

    if ev.measured_last:
        # a tracked target moves by less than a share of its size from where it was or where it is
        # expected
        if contour_clean and not within_reach(contour, ev, cfg):  # type: ignore[arg-type]
            contour_clean = False
        if confident and not within_reach(ev.appearance_box, ev, cfg):  # type: ignore[arg-type]
            confident = False
        if strong_colour and not within_reach(ev.meanshift_box, ev, cfg):  # type: ignore[arg-type]
            strong_colour = False
        # where the colour is seen, a clearly better colour match elsewhere vetoes a contour or a
        # filter detection: the IR shape and the gradients of two people, or two cars, are alike;
        # their colours are not type: ignore[arg-type]
        if contour_clean and colour_elsewhere(contour, ev.rho_contour, ev, cfg):
            contour_clean, colour_says_no = False, True
        # type: ignore[arg-type]
        if confident and colour_elsewhere(ev.appearance_box, ev.rho_appearance, ev, cfg):
            confident = False
        # type: ignore[arg-type]
        if contour_clean and not cut and confident and contour_agrees(contour, ev, cfg):
            return Decision(
                Case.CONTOUR,
                contour,
                1.0,
                TargetStatus.TRACKING,
                "contour-and-appearance",
                True,
                can_learn and not colour_says_no,
                "levelset",
            )
        if confident:
            partial = cut or (ev.contour_reason == ContourReason.COLLAPSE and cfg.contour_checks)
            status = TargetStatus.OCCLUDED_PARTIAL if partial else TargetStatus.TRACKING
            why = (
                "appearance-over-contour"
                if contour_clean
                else f"appearance-contour-{ev.contour_reason}"
            )
            return Decision(
                Case.APPEARANCE,
                ev.appearance_box,
                1.5,
                status,
                why,
                False,
                can_learn and not partial,
                "appearance",
            )
        if contour_clean and not cut:
            if strong_colour and not agree(
                contour, ev.meanshift_box, ev.ref_size, cfg.agree_fraction
            ):  # type: ignore[arg-type]
                return Decision(
                    Case.COLOUR,
                    _resized(ev.meanshift_box, ev.ref_size),
                    2.0,
                    TargetStatus.TRACKING,
                    "colour-against-contour",
                    stage="meanshift",
                )
            # a sharp contour carries the target through colour changes (shadow, darkness); the
            # models do not learn from a frame whose colour contradicts its contour
            return Decision(
                Case.CONTOUR,
                contour,
                1.0,
                TargetStatus.TRACKING,
                "contour-colour-changed" if colour_says_no else "contour",
                True,
                not colour_says_no and not appearance,
                "levelset",
            )
        if strong_colour:
            return Decision(
                Case.COLOUR,
                _resized(ev.meanshift_box, ev.ref_size),
                2.0,
                TargetStatus.TRACKING,
                f"colour-contour-{ev.contour_reason}",
                stage="meanshift",
            )
        if (
            ev.contour_reason == ContourReason.LOW_CONTRAST
            and ev.colour_informative
            and ev.meanshift_box is not None
            and _good(ev.rho_meanshift, cfg.occlusion_rho)
        ):
            return Decision(
                Case.COLOUR,
                _resized(ev.meanshift_box, ev.ref_size),
                2.0,
                TargetStatus.TRACKING,
                "colour-ir-faded",
                stage="meanshift",
            )
        return _coast(ev, cfg, cut)

    # missing: taken back only by a confident cue near where it should be (or found by
    # re-detection)
    colour_agrees = (
        not ev.colour_informative
        or math.isnan(ev.rho_appearance)
        or ev.rho_appearance >= cfg.reacquire_rho
    )
    if (
        appearance
        and _good(ev.psr, cfg.psr_reacquire)
        and (near_prior(ev.appearance_box, ev, cfg) or (ev.redetected and colour_agrees))
    ):  # type: ignore[arg-type]
        # type: ignore[arg-type]
        on_contour = contour_clean and not cut and contour_agrees(contour, ev, cfg)
        return Decision(
            Case.REACQUIRED,
            contour if on_contour else ev.appearance_box,
            1.5,
            TargetStatus.TRACKING,
            REDETECTED if ev.redetected else "appearance-near-prediction",
            False,
            False,
            "levelset" if on_contour else "appearance",
        )
    if (
        contour_clean
        and not cut
        and near_prior(contour, ev, cfg)
        and not confident_elsewhere(ev, cfg)
    ):  # type: ignore[arg-type]
        if (
            not ev.colour_informative
            or _good(ev.rho_contour, cfg.reacquire_rho)
            or math.isnan(ev.rho_contour)
        ):
            return Decision(
                Case.REACQUIRED,
                contour,
                1.0,
                TargetStatus.TRACKING,
                "contour-near-prediction",
                True,
                stage="levelset",
            )
    if (
        ev.colour_informative
        and ev.meanshift_box is not None
        and _good(ev.rho_meanshift, cfg.reacquire_rho)
        and near_prior(ev.meanshift_box, ev, cfg)
        and (strong_colour or ev.contour_reason == ContourReason.LOW_CONTRAST)
    ):
        return Decision(
            Case.REACQUIRED,
            _resized(ev.meanshift_box, ev.ref_size),
            2.0,
            TargetStatus.TRACKING,
            "colour-near-prediction",
            stage="meanshift",
        )
    return _coast(ev, cfg, cut)


def contour_agrees(contour: BBox, ev: Evidence, cfg: DualConfig) -> bool:
    """The contour and the filter's detection agree: centres within ``agree_fraction`` of the size."""
    assert ev.appearance_box is not None
    return agree(contour, ev.appearance_box, ev.ref_size, cfg.agree_fraction)


def within_reach(box: BBox, ev: Evidence, cfg: DualConfig) -> bool:
    """Within ``jump_fraction`` of the target's size (on each axis) of its last box, or of its
    prediction with ``jump_sigma`` standard deviations of the predicted centre added."""

    def near(ref: BBox | None, sx: float = 0.0, sy: float = 0.0) -> bool:
        return ref is not None and (
            abs(box.cx - ref.cx) <= cfg.jump_fraction * ev.ref_size[0] + sx
            and abs(box.cy - ref.cy) <= cfg.jump_fraction * ev.ref_size[1] + sy
        )

    k = cfg.jump_sigma
    return near(ev.prior, k * ev.prior_std_px[0], k * ev.prior_std_px[1]) or near(ev.last)


def colour_elsewhere(box: BBox, rho_at: float, ev: Evidence, cfg: DualConfig) -> bool:
    """The colour says the target is not at ``box``: the match there is under ``colour_min_rho``
    and the mean shift, away from it, matches better by ``colour_veto_margin`` (and at least
    ``colour_min_rho``)."""
    return (
        ev.colour_informative
        and ev.meanshift_box is not None
        and not math.isnan(rho_at)
        and rho_at < cfg.colour_min_rho
        and _good(ev.rho_meanshift, cfg.colour_min_rho)
        and ev.rho_meanshift - rho_at >= cfg.colour_veto_margin
        and not agree(box, ev.meanshift_box, ev.ref_size, cfg.agree_fraction)
    )


def confident_elsewhere(ev: Evidence, cfg: DualConfig) -> bool:
    """A confident filter detection that is not where the contour is."""
    return (
        ev.appearance_box is not None
        and cfg.appearance_cue
        and _good(ev.psr, cfg.psr_confident)
        and ev.contour_box is not None
        and not agree(ev.contour_box, ev.appearance_box, ev.ref_size, cfg.agree_fraction)
    )


def _resized(box: BBox | None, size: tuple[float, float]) -> BBox | None:
    return None if box is None else BBox.from_center(box.cx, box.cy, size[0], size[1])


def _coast(ev: Evidence, cfg: DualConfig, cut: bool) -> Decision:
    missing = ev.missing + 1
    if ev.outside or missing > cfg.max_missing_frames:
        why = "left-the-frame" if ev.outside else f"{missing}-frames-without-a-measurement"
        return Decision(Case.LOST, None, 0.0, TargetStatus.LOST, why)
    evidence = (
        cut
        or (ev.contour_box is not None and ev.contour_ok)
        or (ev.colour_informative and _good(ev.rho_meanshift, cfg.colour_min_rho))
        or (ev.appearance_box is not None and _good(ev.psr, 0.5 * cfg.psr_confident))
    )
    status = TargetStatus.OCCLUDED_PARTIAL if evidence else TargetStatus.OCCLUDED_SEVERE
    return Decision(
        Case.COAST, None, 0.0, status, "partial-evidence" if evidence else "no-evidence"
    )
