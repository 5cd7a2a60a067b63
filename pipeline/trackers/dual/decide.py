"""The dual tracker's per-frame decision: which measurement a target gets, from which cue, and why.

Every cue of a frame is summed up in an :class:`Evidence` (plain values); :class:`View` reads it
once against the decider's thresholds (which cues are confident, within reach, vetoed by the
colour); the :class:`Decider` then applies the first rule of an ordered table whose predicate
holds, and the rule makes the :class:`Decision`: the :class:`Case`, the measurement box, its
noise for the Kalman update, the status and whether the models may learn from it. The same
table serves the dual, the IR-only and the visible-only modes: a cue the mode (or the
configuration) lacks is simply absent from the evidence.

The rules (:class:`Rule`; ``agree`` = centres within ``agree_fraction`` of the target's size):

Tracked last frame (:data:`TRACKED`)
    1. ``CONTOUR_AND_APPEARANCE``: a clean contour that agrees with a confident filter
       detection (both confirm it; the contour's size may be used);
    2. ``APPEARANCE_OVER_CONTOUR`` / ``APPEARANCE_CONTOUR_FAILED``: a confident filter
       detection, the contour elsewhere or failing (where the channels disagree, appearance
       decides);
    3. ``COLOUR_AGAINST_CONTOUR``: a clean contour, the filter unsure, and a strong colour
       match that says the target is elsewhere;
    4. ``CONTOUR_COLOUR_CHANGED`` / ``CONTOUR``: a clean contour (a sharp IR contour carries
       the target through shadows and darkness, where its colour changes);
    5. ``COLOUR_CONTOUR_FAILED``: a strong colour match (colour carries it through IR clutter
       and crossover);
    6. ``COLOUR_IR_FADED``: a contour lost to low contrast and a good colour match;
    then ``PARTIAL_EVIDENCE`` / ``NO_EVIDENCE``: a coast on the motion prior, or
    ``ON_BACKGROUND`` where the filter was confident on a box that differs from a still camera's
    background in under ``background_share`` of its pixels with no colour to confirm it (the
    box has slid off the target; its models stop learning and the re-detection search runs),
    unless the visible channel alone carries a target tracked without a break
    (:func:`visible_carried`: the IR does not see it).

Missing (hidden or lost; :data:`MISSING`)
    7. ``REDETECTED`` / ``APPEARANCE_NEAR_PREDICTION``: a filter detection at ``psr_reacquire``
       near the prediction, or where the target's speed can have carried it since it was last
       seen (``reach_missing``), or found farther by the re-detection search with a colour
       match (where colour is seen) at ``reacquire_rho``; a find away from the prediction
       yields where the mean shift near the prediction matches the colour better
       (``redetect_local_margin``);
    7b. ``APPEARANCE_AND_COLOUR``: a filter detection at ``corroborate_psr`` anywhere, where
       the colour's own search found the target too, each channel's filter peak reaches
       ``psr_reacquire``, no other target's box overlaps it nor its colour model matches better,
       and it differs from a still camera's background (with one channel, that test or a clean
       contour must confirm it; :func:`corroborated`; two cues that agree outvote the motion);
    8. ``CONTOUR_NEAR_PREDICTION``: a clean contour near the prediction whose colour agrees (or
       no colour to ask);
    9. ``COLOUR_NEAR_PREDICTION``: a colour match at ``reacquire_rho`` near the prediction;
    then a coast, which the lifecycle turns into ``LEFT_THE_FRAME`` or ``MISSING_TOO_LONG``.

The other parts decide by rules of the same enum: ``SPLIT_BLOB`` (a member of a group that
split takes its blob), ``WALKED_IN`` (a target given cut by the frame's border takes its first
clean contour), the ``MERGE_*`` placements of a group's members, ``GIVEN`` (frame 1), and
``SHARED``: after every target's own decision, where two targets' measurements are one object
(``shared_iou``, off by default), the better match keeps it and the other is ``merged`` with it
or coasts hidden (:meth:`Decider.yields`; the frame-level step is the tracker's); and a target
whose measurement lies mostly inside another's with its colour not matching there
(``colour_deny_rho``, :meth:`Decider.on_other`) yields to it the same way.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass

from pipeline.stages.contour import ContourReason
from pipeline.tracker_config import DeciderConfig
from pipeline.trackers.dual.state import held
from pipeline.types import BBox, DecisionLabel, TargetStatus

__all__ = [
    "MISSING",
    "TRACKED",
    "Case",
    "Decider",
    "Decision",
    "Evidence",
    "Rule",
    "View",
    "agree",
    "corroborated",
    "needs_background",
]


class Case(enum.StrEnum):
    """Where a frame's measurement of a target came from (the first part of ``targets.csv``'s
    ``decision``, and the .rrd timeline)."""

    INIT = "init"
    CONTOUR = "contour"
    APPEARANCE = "appearance"
    COLOUR = "colour"
    REACQUIRED = "re-acquired"
    COAST = "coast"
    LOST = "lost"
    MERGED = "merged"
    SHARED = "shared"  # on one object with another target, which took the measurement


class Rule(enum.StrEnum):
    """The named rules of the decision; the value is the ``why`` text (``targets.csv``'s
    ``decision`` is ``case:why``), with the rule's details filled in by :meth:`text`."""

    GIVEN = "given"
    CONTOUR_AND_APPEARANCE = "contour-and-appearance"
    APPEARANCE_OVER_CONTOUR = "appearance-over-contour"
    APPEARANCE_CONTOUR_FAILED = "appearance-contour-{reason}"
    COLOUR_AGAINST_CONTOUR = "colour-against-contour"
    CONTOUR_COLOUR_CHANGED = "contour-colour-changed"
    CONTOUR = "contour"
    COLOUR_CONTOUR_FAILED = "colour-contour-{reason}"
    COLOUR_IR_FADED = "colour-ir-faded"
    REDETECTED = "redetected"
    APPEARANCE_NEAR_PREDICTION = "appearance-near-prediction"
    APPEARANCE_AND_COLOUR = "appearance-and-colour"
    CONTOUR_NEAR_PREDICTION = "contour-near-prediction"
    COLOUR_NEAR_PREDICTION = "colour-near-prediction"
    PARTIAL_EVIDENCE = "partial-evidence"
    NO_EVIDENCE = "no-evidence"
    ON_BACKGROUND = "filter-on-background"
    LEFT_THE_FRAME = "left-the-frame"
    MISSING_TOO_LONG = "{missing}-frames-without-a-measurement"
    SHARED = "measurement-taken-by-{reason}"
    SPLIT_BLOB = "split-blob"
    WALKED_IN = "walked-in"
    MERGE_FOREGROUND = "foreground"
    MERGE_KMEANS = "kmeans"
    MERGE_VISIBLE = "visible"
    MERGE_EQ11 = "eq11"
    MERGE_MOTION = "motion"

    def text(self, reason: str = "", missing: int = 0) -> str:
        """The ``why`` of this rule: its value with the contour's ``reason`` or the number of
        ``missing`` frames filled in.

        Examples
        --------
        >>> Rule.APPEARANCE_CONTOUR_FAILED.text(reason="leak")
        'appearance-contour-leak'
        """
        return self.value.format(reason=reason, missing=missing)


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
    support: tuple[float, float] = (float("nan"), float("nan"))  # (visible, IR) PSR at the peak
    last: BBox | None = None  # the previous output box
    redetected: bool = False  # the filter's detection came from the re-detection search
    outside: bool = False  # the prediction has left the frame
    prior_std_px: tuple[float, float] = (0.0, 0.0)  # std. deviation of the predicted centre (x, y)
    contour_checked: bool = True  # the contour cue applies its failure tests (contour.checks)
    contour_part: bool = False  # the contour collapsed to the target's known warm part
    foreground_share: float = float("nan")  # of the filter's box, against the still background
    speed_px: float = 0.0  # its recent speed over its clean measurements, px per frame
    seen: tuple[float, float] | None = None  # centre of its last clean measurement
    seen_frames: int = 0  # frames since that measurement
    on_another: bool = False  # the filter's box overlaps another target's box this frame
    rho_rival: float = float("nan")  # the best other target's colour match at the filter's box

    @property
    def ref_area(self) -> float:
        return self.ref_size[0] * self.ref_size[1]


@dataclass(frozen=True)
class Decision:
    """The outcome: the case, the rule, the measurement (None when coasting), its noise scale,
    the status and why."""

    case: Case
    rule: Rule
    box: BBox | None
    noise: float
    status: TargetStatus
    why: str
    contour_scale: bool = False  # the contour's size may enter the size update
    learn: bool = False  # the models may learn from this frame
    stage: str = "kalman"  # the stage whose box was taken (targets.csv ``source``)
    partial: bool = False  # measured over a cut or collapsed contour

    @property
    def measured(self) -> bool:
        return self.box is not None

    @property
    def held(self) -> bool:
        """This frame is no clean measurement of the target in view
        (:func:`pipeline.trackers.dual.state.held`)."""
        return held(self.status, self.partial)

    @property
    def label(self) -> DecisionLabel:
        """The case and rule with why, as the result carries them to the sinks."""
        return DecisionLabel(self.case, self.rule, self.why)

    @property
    def text(self) -> str:
        """``case:why``, as ``targets.csv``'s ``decision`` column writes it."""
        return str(self.label)


def decision(
    case: Case,
    rule: Rule,
    box: BBox | None = None,
    noise: float = 0.0,
    status: TargetStatus = TargetStatus.TRACKING,
    *,
    reason: str = "",
    missing: int = 0,
    contour_scale: bool = False,
    learn: bool = False,
    stage: str = "kalman",
    partial: bool = False,
) -> Decision:
    """A :class:`Decision` whose ``why`` is ``rule``'s text (the one place it is made)."""
    why = rule.text(reason=reason, missing=missing)
    return Decision(case, rule, box, noise, status, why, contour_scale, learn, stage, partial)


def agree(a: BBox, b: BBox, size: tuple[float, float], fraction: float) -> bool:
    """Centres of ``a`` and ``b`` within ``fraction`` of ``size`` on each axis."""
    return _close(a.center, b.center, size, fraction)


def _close(
    c: tuple[float, float],
    ref: tuple[float, float],
    size: tuple[float, float],
    fraction: float,
    extra: tuple[float, float] = (0.0, 0.0),
) -> bool:
    """Point ``c`` within ``fraction`` of ``size`` plus ``extra`` px of ``ref`` on each axis."""
    return (
        abs(c[0] - ref[0]) <= fraction * size[0] + extra[0]
        and abs(c[1] - ref[1]) <= fraction * size[1] + extra[1]
    )


def _good(x: float, threshold: float) -> bool:
    return not math.isnan(x) and x >= threshold


def _resized(box: BBox | None, size: tuple[float, float]) -> BBox | None:
    return None if box is None else BBox.from_center(box.cx, box.cy, size[0], size[1])


def _clean(ev: Evidence) -> bool:
    """A contour that passed its checks (or any contour, without them)."""
    return ev.contour_box is not None and (ev.contour_ok or not ev.contour_checked)


def _cut(ev: Evidence, cfg: DeciderConfig) -> bool:
    """A checked contour much smaller than the target: something stands in front of it."""
    box = ev.contour_box
    return (
        ev.contour_checked and box is not None and box.area < cfg.partial_area_ratio * ev.ref_area
    )


def _strong_colour(ev: Evidence, cfg: DeciderConfig) -> bool:
    """A colour match at the mean shift strong enough to carry the target alone."""
    if not ev.colour_informative or ev.meanshift_box is None or cfg.colour_trust_rho >= 1:
        return False
    return _good(ev.rho_meanshift, cfg.colour_trust_rho)


def needs_background(ev: Evidence, cfg: DeciderConfig) -> bool:
    """Whether the background test could refuse this frame's filter detection: a confident one
    (``psr_confident``) that neither its colour (``colour_min_rho``) nor a checked contour where
    it is (a contrasted IR blob there) confirms. Only then is the share of its box that differs
    from the background computed (the sequence's background costs seconds on large frames).
    A detection that :func:`corroborated` could take a missing target back with is asked too,
    whatever its colour, unless a contour confirms it."""
    if (
        cfg.background_share <= 0
        or ev.appearance_box is None
        or not _good(ev.psr, cfg.psr_confident)
    ):
        return False
    on_contour = _clean(ev) and agree(
        ev.contour_box, ev.appearance_box, ev.ref_size, cfg.agree_fraction
    )
    if on_contour or visible_carried(ev, cfg):
        return False
    if corroborated(ev, cfg):
        return True
    return not (ev.colour_informative and _good(ev.rho_appearance, cfg.colour_min_rho))


def corroborated(ev: Evidence, cfg: DeciderConfig) -> bool:
    """Whether the other cues confirm the filter's detection of a missing target, so that it
    may take the target back far from its prediction (``corroborate_psr``): a peak of that
    PSR, at ``psr_reacquire`` in each channel that has one, where the mean shift (the
    colour's own search) converged too, on no other target's box, and that no other target's
    colour model matches better than its own (``rho_rival``). The background test is
    :attr:`View.corroborated`'s.

    Examples
    --------
    >>> from pipeline.tracker_config import DeciderConfig
    >>> at = lambda cx: BBox.from_center(cx, 100, 12, 24)
    >>> ev = Evidence(measured_last=False, missing=2, prior=at(100), ref_size=(12, 24),
    ...               colour_informative=True, rho_meanshift=0.3, meanshift_box=at(141),
    ...               contour_box=None, contour_ok=False, contour_reason="no-component",
    ...               rho_contour=float("nan"), appearance_box=at(140), psr=20.0,
    ...               rho_appearance=0.3, support=(15.0, 11.0))
    >>> corroborated(ev, DeciderConfig())
    True
    >>> import dataclasses
    >>> corroborated(dataclasses.replace(ev, support=(15.0, 2.0)), DeciderConfig())
    False
    """
    return (
        cfg.corroborate_psr > 0
        and not ev.measured_last
        and _good(ev.psr, cfg.corroborate_psr)
        and all(math.isnan(p) or p >= cfg.psr_reacquire for p in ev.support)
        and _colour_on_filter(ev, cfg)
        and not (ev.on_another or ev.rho_rival > ev.rho_appearance)
    )


def _colour_on_filter(ev: Evidence, cfg: DeciderConfig) -> bool:
    """The mean shift converged where the filter's detection is (``agree_fraction``)."""
    return (
        ev.colour_informative
        and ev.meanshift_box is not None
        and ev.appearance_box is not None
        and agree(ev.appearance_box, ev.meanshift_box, ev.ref_size, cfg.agree_fraction)
    )


def visible_carried(ev: Evidence, cfg: DeciderConfig) -> bool:
    """Whether the visible channel alone carries the filter's detection of a target tracked
    without a break (``visible_carries_psr``): measured cleanly on the frame before, its
    visible peak at that PSR, its IR peak under ``psr_reacquire``. The IR background test
    cannot refuse such a detection: the IR does not see this target.

    Examples
    --------
    >>> from pipeline.tracker_config import DeciderConfig
    >>> at = BBox.from_center(100, 100, 12, 24)
    >>> ev = Evidence(measured_last=True, missing=0, prior=at, ref_size=(12, 24),
    ...               colour_informative=True, rho_meanshift=0.3, meanshift_box=at,
    ...               contour_box=None, contour_ok=False, contour_reason="no-component",
    ...               rho_contour=float("nan"), appearance_box=at, psr=20.0,
    ...               rho_appearance=0.3, support=(20.0, 3.0), seen=(100, 100), seen_frames=1)
    >>> visible_carried(ev, DeciderConfig())
    True
    >>> import dataclasses
    >>> visible_carried(dataclasses.replace(ev, seen_frames=40), DeciderConfig())
    False
    >>> visible_carried(dataclasses.replace(ev, support=(20.0, 9.0)), DeciderConfig())
    False
    """
    vis, ir = ev.support
    return (
        cfg.visible_carries_psr > 0
        and ev.measured_last
        and ev.seen is not None
        and ev.seen_frames <= 1
        and _good(vis, cfg.visible_carries_psr)
        and not _good(ir, cfg.psr_reacquire)
    )


def _on_background(ev: Evidence, cfg: DeciderConfig) -> bool:
    """The filter's box differs from the still camera's background in under
    ``background_share`` of its pixels, its colour does not confirm it, and the visible
    channel does not carry it alone (:func:`visible_carried`)."""
    if cfg.background_share <= 0 or math.isnan(ev.foreground_share) or visible_carried(ev, cfg):
        return False
    confirmed = ev.colour_informative and _good(ev.rho_appearance, cfg.colour_min_rho)
    return ev.foreground_share < cfg.background_share and not confirmed


def _colour_says_no(ev: Evidence, cfg: DeciderConfig) -> bool:
    """The colour at the contour contradicts it (under ``colour_min_rho``)."""
    return (
        ev.colour_informative
        and not math.isnan(ev.rho_contour)
        and ev.rho_contour < cfg.colour_min_rho
    )


@dataclass(frozen=True)
class View:
    """The evidence of one frame read once against the decider's thresholds.

    For a target measured in the previous frame, ``contour_clean``, ``confident`` and
    ``strong_colour`` are already narrowed to measurements within its reach, and a contour or
    filter detection that a clearly better colour match elsewhere vetoes is no longer clean or
    confident; for a missing target they are as the cues found them. ``cut`` (a clean contour
    much smaller than the target) is as found.
    """

    ev: Evidence
    cfg: DeciderConfig
    appearance: bool  # the filter detected something
    can_learn: bool  # the filter's detection is good enough to learn from (or there is none)
    contour_clean: bool
    cut: bool
    confident: bool
    strong_colour: bool
    colour_says_no: bool  # the colour at the contour contradicts it

    @classmethod
    def of(cls, ev: Evidence, cfg: DeciderConfig) -> View:
        """Read ``ev`` against ``cfg`` (the flags of the class doc)."""
        appearance = ev.appearance_box is not None
        clean = _clean(ev)
        v = cls(
            ev,
            cfg,
            appearance,
            can_learn=not appearance or _good(ev.psr, cfg.psr_update),
            contour_clean=clean,
            cut=clean and _cut(ev, cfg),
            confident=appearance
            and _good(ev.psr, cfg.psr_confident)
            and not _on_background(ev, cfg),
            strong_colour=_strong_colour(ev, cfg),
            colour_says_no=_colour_says_no(ev, cfg),
        )
        return v._narrowed() if ev.measured_last else v

    def _narrowed(self) -> View:
        """A tracked target moves by less than a share of its size from where it was or where
        it is expected; where the colour is seen, a clearly better colour match elsewhere
        vetoes a contour or a filter detection (the IR shape and the gradients of two people,
        or two cars, are alike; their colours are not)."""
        ev = self.ev
        clean = self.contour_clean and self.within_reach(ev.contour_box)
        confident = self.confident and self.within_reach(ev.appearance_box)
        strong = self.strong_colour and self.within_reach(ev.meanshift_box)
        says_no = self.colour_says_no
        if clean and self.colour_elsewhere(ev.contour_box, ev.rho_contour):
            clean, says_no = False, True
        if confident and self.colour_elsewhere(ev.appearance_box, ev.rho_appearance):
            confident = False
        return View(
            ev,
            self.cfg,
            self.appearance,
            self.can_learn,
            clean,
            self.cut,
            confident,
            strong,
            says_no,
        )

    # -- geometry --------------------------------------------------------------------------
    def agree(self, a: BBox | None, b: BBox | None) -> bool:
        """Both boxes exist and their centres agree (``agree_fraction`` of the size)."""
        return (
            a is not None
            and b is not None
            and agree(a, b, self.ev.ref_size, self.cfg.agree_fraction)
        )

    def within_reach(self, box: BBox) -> bool:
        """Within ``jump_fraction`` of the target's size (on each axis) of its last box, with
        ``jump_speed`` times its recent speed added (a turn or a stop), or of its prediction
        with ``jump_sigma`` standard deviations of the predicted centre added."""
        ev, cfg = self.ev, self.cfg

        def near(ref: BBox | None, extra: tuple[float, float]) -> bool:
            return ref is not None and _close(
                box.center, ref.center, ev.ref_size, cfg.jump_fraction, extra
            )

        k, s = cfg.jump_sigma, cfg.jump_speed * ev.speed_px
        return near(ev.prior, (k * ev.prior_std_px[0], k * ev.prior_std_px[1])) or near(
            ev.last, (s, s)
        )

    def near_prior(self, box: BBox | None) -> bool:
        """``box`` exists and lies near the prediction (:meth:`Decider.near_prediction`)."""
        ev = self.ev
        return box is not None and near_prediction(
            box.center, ev.prior.center, ev.ref_size, ev.missing, self.cfg
        )

    def colour_elsewhere(self, box: BBox, rho_at: float) -> bool:
        """The colour says the target is not at ``box``: the match there is under
        ``colour_min_rho`` and the mean shift, away from it, matches better by
        ``colour_veto_margin`` (and at least ``colour_min_rho``)."""
        ev, cfg = self.ev, self.cfg
        return (
            ev.colour_informative
            and ev.meanshift_box is not None
            and not math.isnan(rho_at)
            and rho_at < cfg.colour_min_rho
            and _good(ev.rho_meanshift, cfg.colour_min_rho)
            and ev.rho_meanshift - rho_at >= cfg.colour_veto_margin
            and not agree(box, ev.meanshift_box, ev.ref_size, cfg.agree_fraction)
        )

    # -- shared readings -------------------------------------------------------------------
    @property
    def contour_usable(self) -> bool:
        """A clean contour that is not cut by something in front."""
        return self.contour_clean and not self.cut

    @property
    def contour_on_filter(self) -> bool:
        """A usable contour where the filter's detection is."""
        return self.contour_usable and self.agree(self.ev.contour_box, self.ev.appearance_box)

    @property
    def partial(self) -> bool:
        """The filter measures over a cut or collapsed contour (not one collapsed to the
        target's known warm part)."""
        ev = self.ev
        collapsed = ev.contour_reason == ContourReason.COLLAPSE and not ev.contour_part
        return self.cut or (collapsed and ev.contour_checked)

    @property
    def hidden_part(self) -> bool:
        """Part of the target is hidden: its contour is cut, or collapsed where the colour at the
        filter's box does not match the whole target (``whole_colour_rho``; where it does, the
        infrared lost a target that is all there: one near the ground's temperature)."""
        ev, cfg = self.ev, self.cfg
        whole = (
            cfg.whole_colour_rho < 1
            and ev.colour_informative
            and _good(ev.rho_appearance, cfg.whole_colour_rho)
        )
        return self.cut or (self.partial and not whole)

    @property
    def reacquirable(self) -> bool:
        """A filter detection strong enough to take a missing target back, where the target
        may be (:meth:`find_placed`) and no better colour match near the prediction says it
        is still there (:meth:`local_better`)."""
        ev, cfg = self.ev, self.cfg
        return (
            self.appearance
            and _good(ev.psr, cfg.psr_reacquire)
            and not _on_background(ev, cfg)
            and self.find_placed
            and not (ev.redetected and self.local_better(ev.appearance_box, ev.rho_appearance))
        )

    @property
    def find_placed(self) -> bool:
        """The filter's detection lies near the prediction, or was found by the re-detection
        search with the colour agreeing (``reacquire_rho``), or where the target can have got
        to (:meth:`reached`)."""
        ev, cfg = self.ev, self.cfg
        colour_agrees = (
            not ev.colour_informative
            or math.isnan(ev.rho_appearance)
            or ev.rho_appearance >= cfg.reacquire_rho
        )
        return (
            self.near_prior(ev.appearance_box)
            or (ev.redetected and colour_agrees)
            or self.reached(ev.appearance_box)
        )

    @property
    def corroborated(self) -> bool:
        """The filter's detection is :func:`corroborated` and its box differs from a still
        camera's background in at least ``background_share`` of its pixels, whatever its
        colour (a background structure that matches the target's colours and gradients stays
        where it is). A second, independent check is needed: the filter's peak in both
        channels, that background test, or a clean contour on the find. With one channel and
        neither (visible footage alone) the colour and the gradients of one image are not
        enough: a look-alike fools both."""
        ev, cfg = self.ev, self.cfg
        if not corroborated(ev, cfg):
            return False
        share, fg = cfg.background_share, ev.foreground_share
        both = not any(math.isnan(p) for p in ev.support)
        tested = share > 0 and not math.isnan(fg)
        return (both or tested or self.contour_on_filter) and not (tested and fg < share)

    def local_better(self, box: BBox | None, rho_at: float) -> bool:
        """``box`` lies away from the prediction, and the mean shift near the prediction
        matches the target's colour better than ``box`` does (``rho_at``) by
        ``redetect_local_margin``."""
        ev, cfg = self.ev, self.cfg
        return (
            box is not None
            and not self.near_prior(box)
            and ev.colour_informative
            and ev.meanshift_box is not None
            and not math.isnan(rho_at)
            and not math.isnan(ev.rho_meanshift)
            and ev.rho_meanshift - rho_at >= cfg.redetect_local_margin
            and self.near_prior(ev.meanshift_box)
            and not self.agree(box, ev.meanshift_box)
        )

    def reached(self, box: BBox | None) -> bool:
        """``box`` lies where the target can have got to since its last clean measurement:
        within ``jump_fraction`` of its size plus ``jump_speed`` times its recent speed for
        every frame since (``reach_missing``), and the colour does not say it is elsewhere;
        found by the re-detection search (many places tried), its colour must also match at
        ``colour_deny_rho``."""
        ev, cfg = self.ev, self.cfg
        if not cfg.reach_missing or box is None or ev.seen is None:
            return False
        r = cfg.jump_speed * ev.speed_px * ev.seen_frames
        return (
            _close(box.center, ev.seen, ev.ref_size, cfg.jump_fraction, (r, r))
            and not self.colour_elsewhere(box, ev.rho_appearance)
            and not (
                ev.redetected and ev.colour_informative and ev.rho_appearance < cfg.colour_deny_rho
            )
        )

    @property
    def colour_seen(self) -> bool:
        """A good enough colour match (``occlusion_rho``) at the mean shift."""
        ev = self.ev
        return (
            ev.colour_informative
            and ev.meanshift_box is not None
            and _good(ev.rho_meanshift, self.cfg.occlusion_rho)
        )

    @property
    def some_evidence(self) -> bool:
        """Something of the target is seen although nothing measures it: ``occluded-partial``
        rather than ``occluded-severe``."""
        ev, cfg = self.ev, self.cfg
        return (
            self.cut
            or (ev.contour_box is not None and ev.contour_ok)
            or (ev.colour_informative and _good(ev.rho_meanshift, cfg.colour_min_rho))
            or (
                ev.appearance_box is not None
                and _good(ev.psr, cfg.weak_psr_fraction * cfg.psr_confident)
            )
        )


def near_prediction(
    center: tuple[float, float],
    predicted: tuple[float, float],
    ref_size: tuple[float, float],
    missing: int,
    cfg: DeciderConfig,
) -> bool:
    """``center`` within half of ``ref_size`` of ``predicted``, plus
    ``reacquire_gate_px_per_frame`` per ``missing`` frame."""
    extra = cfg.reacquire_gate_px_per_frame * missing
    return _close(center, predicted, ref_size, 0.5, (extra, extra))


# ------------------------------------------------------------------------------ the rules
# Each rule: (name, predicate over the view, the decision it makes). The first whose predicate
# holds decides; predicates may assume the earlier rules did not apply.

RuleSpec = tuple[Rule, Callable[[View], bool], Callable[[View], Decision]]


def _contour(v: View, rule: Rule, learn: bool) -> Decision:
    return decision(
        Case.CONTOUR,
        rule,
        v.ev.contour_box,
        v.cfg.noise_scale_contour,
        contour_scale=True,
        learn=learn,
        stage="levelset",
    )


def _appearance(v: View, rule: Rule) -> Decision:
    partial = v.partial
    status = TargetStatus.OCCLUDED_PARTIAL if v.hidden_part else TargetStatus.TRACKING
    return decision(
        Case.APPEARANCE,
        rule,
        v.ev.appearance_box,
        v.cfg.noise_scale_appearance,
        status,
        reason=v.ev.contour_reason,
        learn=v.can_learn and not v.hidden_part,
        stage="appearance",
        partial=partial,
    )


def _colour(v: View, rule: Rule, case: Case = Case.COLOUR) -> Decision:
    box = _resized(v.ev.meanshift_box, v.ev.ref_size)
    return decision(
        case, rule, box, v.cfg.noise_scale_colour, reason=v.ev.contour_reason, stage="meanshift"
    )


def _reacquired_by_filter(v: View, rule: Rule) -> Decision:
    on = v.contour_on_filter
    return decision(
        Case.REACQUIRED,
        rule,
        v.ev.contour_box if on else v.ev.appearance_box,
        v.cfg.noise_scale_appearance,
        stage="levelset" if on else "appearance",
    )


def _contour_near_prediction(v: View) -> bool:
    ev = v.ev
    confident_elsewhere = v.confident and ev.contour_box is not None and not v.contour_on_filter
    colour_ok = (
        not ev.colour_informative
        or _good(ev.rho_contour, v.cfg.reacquire_rho)
        or math.isnan(ev.rho_contour)
    )
    return (
        v.contour_usable and v.near_prior(ev.contour_box) and not confident_elsewhere and colour_ok
    )


def _colour_near_prediction(v: View) -> bool:
    ev = v.ev
    return (
        ev.colour_informative
        and ev.meanshift_box is not None
        and _good(ev.rho_meanshift, v.cfg.reacquire_rho)
        and v.near_prior(ev.meanshift_box)
        and (v.strong_colour or ev.contour_reason == ContourReason.LOW_CONTRAST)
    )


TRACKED: tuple[RuleSpec, ...] = (
    (
        Rule.CONTOUR_AND_APPEARANCE,
        lambda v: v.contour_usable and v.confident and v.contour_on_filter,
        lambda v: _contour(v, Rule.CONTOUR_AND_APPEARANCE, v.can_learn and not v.colour_says_no),
    ),
    (
        Rule.APPEARANCE_OVER_CONTOUR,
        lambda v: v.confident and v.contour_clean,
        lambda v: _appearance(v, Rule.APPEARANCE_OVER_CONTOUR),
    ),
    (
        Rule.APPEARANCE_CONTOUR_FAILED,
        lambda v: v.confident,
        lambda v: _appearance(v, Rule.APPEARANCE_CONTOUR_FAILED),
    ),
    (
        Rule.COLOUR_AGAINST_CONTOUR,
        lambda v: (
            v.contour_usable
            and v.strong_colour
            and not v.agree(v.ev.contour_box, v.ev.meanshift_box)
        ),
        lambda v: _colour(v, Rule.COLOUR_AGAINST_CONTOUR),
    ),
    (
        Rule.CONTOUR_COLOUR_CHANGED,
        lambda v: v.contour_usable and v.colour_says_no,
        lambda v: _contour(v, Rule.CONTOUR_COLOUR_CHANGED, False),
    ),
    (
        Rule.CONTOUR,
        lambda v: v.contour_usable,
        lambda v: _contour(v, Rule.CONTOUR, not v.appearance),
    ),
    (
        Rule.COLOUR_CONTOUR_FAILED,
        lambda v: v.strong_colour,
        lambda v: _colour(v, Rule.COLOUR_CONTOUR_FAILED),
    ),
    (
        Rule.COLOUR_IR_FADED,
        lambda v: v.ev.contour_reason == ContourReason.LOW_CONTRAST and v.colour_seen,
        lambda v: _colour(v, Rule.COLOUR_IR_FADED),
    ),
)
"""The rules for a target measured in the previous frame, in order."""

MISSING: tuple[RuleSpec, ...] = (
    (
        Rule.REDETECTED,
        lambda v: v.reacquirable and v.ev.redetected,
        lambda v: _reacquired_by_filter(v, Rule.REDETECTED),
    ),
    (
        Rule.APPEARANCE_NEAR_PREDICTION,
        lambda v: v.reacquirable,
        lambda v: _reacquired_by_filter(v, Rule.APPEARANCE_NEAR_PREDICTION),
    ),
    (
        Rule.APPEARANCE_AND_COLOUR,
        lambda v: v.appearance and _good(v.ev.psr, v.cfg.psr_reacquire) and v.corroborated,
        lambda v: _reacquired_by_filter(v, Rule.APPEARANCE_AND_COLOUR),
    ),
    (
        Rule.CONTOUR_NEAR_PREDICTION,
        _contour_near_prediction,
        lambda v: decision(
            Case.REACQUIRED,
            Rule.CONTOUR_NEAR_PREDICTION,
            v.ev.contour_box,
            v.cfg.noise_scale_contour,
            contour_scale=True,
            stage="levelset",
        ),
    ),
    (
        Rule.COLOUR_NEAR_PREDICTION,
        _colour_near_prediction,
        lambda v: _colour(v, Rule.COLOUR_NEAR_PREDICTION, Case.REACQUIRED),
    ),
)
"""The rules for a target missing (hidden or lost), in order."""


def coast(v: View) -> Decision:
    """No rule applies: the target coasts on its motion prior, ``occluded-partial`` with some
    evidence of it (``ON_BACKGROUND`` where that was a confident filter on the background),
    ``occluded-severe`` without."""
    ev = v.ev
    if v.appearance and _good(ev.psr, v.cfg.psr_confident) and _on_background(ev, v.cfg):
        return decision(Case.COAST, Rule.ON_BACKGROUND, status=TargetStatus.OCCLUDED_PARTIAL)
    if v.some_evidence:
        return decision(Case.COAST, Rule.PARTIAL_EVIDENCE, status=TargetStatus.OCCLUDED_PARTIAL)
    return decision(Case.COAST, Rule.NO_EVIDENCE, status=TargetStatus.OCCLUDED_SEVERE)


@dataclass(frozen=True)
class Decider:
    """The decision part of the dual tracker: the rule table over a frame's evidence, and the
    thresholds the other parts read the cues by (``dual.decider``)."""

    cfg: DeciderConfig

    def decide(self, ev: Evidence) -> Decision:
        """The measurement of one target in one frame: the first rule of :data:`TRACKED` (or
        :data:`MISSING` for a target without a measurement last frame) that holds, else a
        coast.

        Examples
        --------
        A clean contour where a confident filter detection is (rule 1), then the same frame
        with the contour leaking into a neighbour (rule 2):

        >>> from pipeline.tracker_config import DeciderConfig
        >>> from pipeline.trackers.dual import Decider, Evidence, Rule
        >>> from pipeline.types import BBox
        >>> at = lambda cx: BBox.from_center(cx, 100, 20, 50)
        >>> ev = Evidence(measured_last=True, missing=0, prior=at(100), ref_size=(20, 50),
        ...               colour_informative=True, rho_meanshift=0.9, meanshift_box=at(101),
        ...               contour_box=at(100.5), contour_ok=True, contour_reason="ok",
        ...               rho_contour=0.9, appearance_box=at(100.2), psr=15.0, rho_appearance=0.9)
        >>> decider = Decider(DeciderConfig())
        >>> d = decider.decide(ev)
        >>> d.rule == Rule.CONTOUR_AND_APPEARANCE, d.text, d.stage
        (True, 'contour:contour-and-appearance', 'levelset')
        >>> import dataclasses
        >>> d = decider.decide(dataclasses.replace(ev, contour_ok=False, contour_reason="leak"))
        >>> d.text, d.box == at(100.2)
        ('appearance:appearance-contour-leak', True)
        """
        v = View.of(ev, self.cfg)
        for _, holds, make in TRACKED if ev.measured_last else MISSING:
            if holds(v):
                return make(v)
        return coast(v)

    def split_blob(self, box: BBox) -> Decision:
        """A member of a group that split takes the blob it was re-associated with (``SPLIT_BLOB``)
        when no cue measures it."""
        return decision(
            Case.CONTOUR,
            Rule.SPLIT_BLOB,
            box,
            self.cfg.noise_scale_contour,
            contour_scale=True,
            stage="levelset",
        )

    def yields(
        self, owner: int, box: BBox, prior: BBox, on_object: bool | None = None
    ) -> Decision:
        """A target whose measurement ``box`` target ``owner`` took (a frame-level decision over
        both, :meth:`owner_of`); it learns nothing (``SHARED``). Where its own prediction
        ``prior`` lies on that object too (``on_object``; by default IoU at least
        ``shared_iou``), the two are one blob: it is ``merged`` and keeps to its own motion (its
        prediction is its measurement, so it neither counts as missing nor follows the other's
        box, and leaves the blob with its own velocity); else the measurement pulled it onto the
        other target and it coasts, partly hidden."""
        if on_object is None:
            on_object = prior.iou(box) >= self.cfg.shared_iou
        if on_object:
            return decision(
                Case.SHARED,
                Rule.SHARED,
                prior,
                self.cfg.noise_scale_colour,
                TargetStatus.MERGED,
                reason=f"T{owner}",
            )
        return decision(
            Case.COAST, Rule.SHARED, status=TargetStatus.OCCLUDED_PARTIAL, reason=f"T{owner}"
        )

    def shared(self, a: BBox | None, b: BBox | None) -> bool:
        """Whether two targets' measurements ``a`` and ``b`` are one object (IoU at least
        ``shared_iou``)."""
        if a is None or b is None or self.cfg.shared_iou <= 0:
            return False
        return a.iou(b) >= self.cfg.shared_iou

    def on_other(self, a: BBox, b: BBox, rho_a: float) -> bool:
        """Whether the measurement ``a`` of a target whose colour matches ``rho_a`` there lies
        on another target measured at ``b``: mostly inside it (``inside_fraction`` of its area)
        with its colour under ``colour_deny_rho``."""
        cfg = self.cfg
        if cfg.colour_deny_rho <= 0 or math.isnan(rho_a) or rho_a >= cfg.colour_deny_rho:
            return False
        return self.lies_in(a, b)

    def lies_in(self, a: BBox, b: BBox) -> bool:
        """Whether box ``a`` lies mostly inside box ``b`` (``inside_fraction`` of its area)."""
        return a.intersect(b).area >= self.cfg.inside_fraction * a.area

    def owner_of(
        self,
        rho: tuple[float, float],
        reach: tuple[float, float],
        held: tuple[bool, bool] = (True, True),
    ) -> int:
        """Which of two targets (0 or 1) owns a shared measurement: the one that held it (was
        measured last frame, ``held``) against one that comes back to it from a coast (the
        newcomer's model may have learned the object while it sat on it wrongly); between
        equals, the one whose colour model matches it better by ``shared_colour_margin``
        (``rho``, each at its own box), else the one whose prediction lies nearer (``reach``:
        distance over its size).

        Examples
        --------
        >>> from pipeline.tracker_config import DeciderConfig
        >>> d = Decider(DeciderConfig())
        >>> d.owner_of((0.6, 0.9), (0.1, 0.8)), d.owner_of((0.88, 0.9), (0.1, 0.8))
        (1, 0)
        >>> d.owner_of((float("nan"), 0.9), (0.5, 0.2))
        1
        >>> d.owner_of((0.6, 0.9), (0.1, 0.8), held=(True, False))
        0
        """
        if held[0] != held[1]:
            return 0 if held[0] else 1
        m = self.cfg.shared_colour_margin
        if not (math.isnan(rho[0]) or math.isnan(rho[1])) and abs(rho[0] - rho[1]) >= m:
            return 0 if rho[0] > rho[1] else 1
        return 0 if reach[0] <= reach[1] else 1

    def walked_in(self, box: BBox) -> Decision:
        """A target given cut by the frame's border takes its first clean contour once it has
        walked in (``WALKED_IN``)."""
        return decision(
            Case.CONTOUR, Rule.WALKED_IN, box, self.cfg.noise_scale_contour, stage="levelset"
        )

    # -- readings the other parts use ------------------------------------------------------
    def filter_confident(self, psr: float) -> bool:
        """A filter detection of this PSR is confident (``psr_confident``)."""
        return psr >= self.cfg.psr_confident

    def colour_good(self, informative: bool, rho: float) -> bool:
        """A colour match good enough to carry the target (``occlusion_rho``)."""
        return informative and rho >= self.cfg.occlusion_rho

    def colour_contradicts(self, rho: float) -> bool:
        """A colour match that contradicts a measurement (under ``colour_min_rho``)."""
        return not math.isnan(rho) and rho < self.cfg.colour_min_rho

    def colour_moved(
        self,
        informative: bool,
        rho: float,
        found: tuple[float, float],
        expected: tuple[float, float],
        size: tuple[float, float],
        psr: float,
    ) -> bool:
        """The colour found the target (a match of ``colour_min_rho``) away from where it was
        expected (beyond ``agree_fraction`` of its size) while the filter is unsure there
        (under ``psr_reacquire``): a turn, where the filter should look too."""
        cfg = self.cfg
        return (
            informative
            and rho >= cfg.colour_min_rho
            and psr < cfg.psr_reacquire
            and not _close(found, expected, size, cfg.agree_fraction)
        )

    def turns(
        self,
        psr: float,
        seen: tuple[float, float] | None,
        predicted: tuple[float, float],
        tried: tuple[float, float],
        size: tuple[float, float],
    ) -> list[tuple[float, float]]:
        """Where else the filter looks when it is not confident (under ``psr_confident``) at
        ``tried``: where a stop leaves the target (``seen``, its last clean measurement) and
        where a reversal takes it (as far behind ``seen`` as ``predicted`` is ahead of it),
        each only where it differs from the places already tried by more than
        ``agree_fraction`` of the size (``turn_search``).

        Examples
        --------
        >>> from pipeline.tracker_config import DeciderConfig
        >>> Decider(DeciderConfig()).turns(3.0, (50.0, 50.0), (60.0, 50.0), (60.0, 50.0), (10, 20))
        [(50.0, 50.0), (40.0, 50.0)]
        >>> Decider(DeciderConfig()).turns(8.0, (50.0, 50.0), (60.0, 50.0), (60.0, 50.0), (10, 20))
        []
        """
        cfg = self.cfg
        if not cfg.turn_search or seen is None or psr >= cfg.psr_confident:
            return []
        back = (2.0 * seen[0] - predicted[0], 2.0 * seen[1] - predicted[1])
        out: list[tuple[float, float]] = []
        for c in (seen, back):
            if not any(_close(c, q, size, cfg.agree_fraction) for q in (tried, *out)):
                out.append(c)
        return out

    def takes_back(
        self,
        psr: float,
        center: tuple[float, float],
        predicted: tuple[float, float],
        ref_size: tuple[float, float],
        missing: int,
    ) -> bool:
        """A filter detection that rule 7 takes a missing target back with: at
        ``psr_reacquire``, near the prediction."""
        return psr >= self.cfg.psr_reacquire and near_prediction(
            center, predicted, ref_size, missing, self.cfg
        )
