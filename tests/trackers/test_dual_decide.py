"""The dual tracker's decision, rule by rule (``pipeline.trackers.dual.decide``)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from pipeline.tracker_config import DeciderConfig, LifecycleConfig, RedetectConfig, SizeConfig
from pipeline.trackers.dual import Case, Decider, Decision, Evidence, Rule
from pipeline.trackers.dual.decide import MISSING, TRACKED
from pipeline.trackers.dual.lifecycle import Lifecycle
from pipeline.types import BBox, TargetStatus

CFG = DeciderConfig()
LIFE = LifecycleConfig()
NAN = math.nan
SIZE = (20.0, 50.0)
PRIOR = BBox.from_center(100, 100, *SIZE)


def at(cx: float, cy: float = 100.0, w: float = SIZE[0], h: float = SIZE[1]) -> BBox:
    return BBox.from_center(cx, cy, w, h)


def decide(ev: Evidence, cfg: DeciderConfig = CFG) -> Decision:
    """The decider's decision, settled by the lifecycle (a coast gone on too long is lost)."""
    return Lifecycle(LIFE).settle(Decider(cfg).decide(ev), ev)


def evidence(**kw) -> Evidence:
    """A tracked target whose every cue agrees at the prediction; ``kw`` changes what one cue
    found."""
    base = dict(
        measured_last=True,
        missing=0,
        prior=PRIOR,
        ref_size=SIZE,
        colour_informative=True,
        rho_meanshift=0.9,
        meanshift_box=at(101),
        contour_box=at(100.5),
        contour_ok=True,
        contour_reason="ok",
        rho_contour=0.9,
        appearance_box=at(100.2),
        psr=15.0,
        rho_appearance=0.9,
        support=(10.0, 10.0),
        last=at(98),
    )
    base.update(kw)
    return Evidence(**base)


def missing(frames: int = 5, **kw) -> Evidence:
    """A target hidden for ``frames`` frames (its prediction at PRIOR)."""
    nothing = dict(
        meanshift_box=None,
        rho_meanshift=NAN,
        contour_box=None,
        contour_ok=False,
        contour_reason="no-component",
        rho_contour=NAN,
        appearance_box=None,
        psr=NAN,
        rho_appearance=NAN,
    )
    nothing.update(kw)
    return evidence(measured_last=False, missing=frames, **nothing)


COLLAPSED = dict(contour_box=None, contour_ok=False, contour_reason="collapse", rho_contour=NAN)
"""The contour collapsed under the filter's box (under ``min_area_fraction`` of the target)."""


@pytest.mark.parametrize(
    ("rho", "informative", "whole_rho", "status"),
    [
        (0.95, True, 0.9, TargetStatus.TRACKING),  # all of it is there: the infrared lost it
        (0.9, True, 0.9, TargetStatus.TRACKING),
        (0.85, True, 0.9, TargetStatus.OCCLUDED_PARTIAL),  # part of the box is something else
        (NAN, True, 0.9, TargetStatus.OCCLUDED_PARTIAL),
        (0.95, False, 0.9, TargetStatus.OCCLUDED_PARTIAL),  # a dark frame's colour says nothing
        (0.95, True, 1.0, TargetStatus.OCCLUDED_PARTIAL),  # 1: every collapse is an occlusion
    ],
)
def test_a_collapsed_contour_under_the_whole_targets_colour_is_no_occlusion(
    rho, informative, whole_rho, status
):
    """The filter measures over a collapsed contour: the status says partly hidden unless the
    colour at the filter's box matches the whole target (``whole_colour_rho``), and only then may
    the models learn from the frame. Either way it is measured over partial evidence: the motion
    holds (``held``), as for a partly hidden target."""
    cfg = dataclasses.replace(CFG, whole_colour_rho=whole_rho)
    ev = evidence(**COLLAPSED, rho_appearance=rho, colour_informative=informative)
    d = decide(ev, cfg)
    assert (d.case, d.status) == (Case.APPEARANCE, status)
    assert d.partial and d.held and d.learn == (status == TargetStatus.TRACKING)
    clean = decide(evidence(rho_appearance=rho, colour_informative=informative), cfg)
    assert not clean.partial and not clean.held


# ----------------------------------------------------------------------------------------- tracked


def test_contour_confirmed_by_the_filter():
    d = decide(evidence())
    assert (d.case, d.status, d.rule, d.stage) == (
        Case.CONTOUR,
        TargetStatus.TRACKING,
        Rule.CONTOUR_AND_APPEARANCE,
        "levelset",
    )
    assert d.box == at(100.5) and d.contour_scale and d.learn and d.noise == 1.0


def test_appearance_decides_where_the_contour_fails():
    d = decide(evidence(contour_ok=False, contour_reason="leak", contour_box=at(110, w=60)))
    assert (d.case, d.status, d.rule, d.stage) == (
        Case.APPEARANCE,
        TargetStatus.TRACKING,
        Rule.APPEARANCE_CONTOUR_FAILED,
        "appearance",
    )
    assert d.box == at(100.2) and not d.contour_scale and d.learn


def test_appearance_decides_where_contour_and_filter_disagree():
    d = decide(evidence(contour_box=at(111)))  # the contour went 11 px (0.55 widths) aside
    assert (d.case, d.rule) == (Case.APPEARANCE, Rule.APPEARANCE_OVER_CONTOUR)


def test_a_cut_contour_with_the_filter_is_a_partial_occlusion():
    d = decide(evidence(contour_box=at(100, 115, h=20)))  # 40 % of the usual box
    assert (d.case, d.status) == (Case.APPEARANCE, TargetStatus.OCCLUDED_PARTIAL)
    assert not d.learn  # an occluder in front does not teach the models


def test_a_sharp_contour_carries_the_target_through_a_colour_change():
    """A shadow: the colour at the contour falls under colour_min_rho, no colour matches better
    elsewhere."""
    d = decide(evidence(rho_contour=0.4, rho_meanshift=0.45, rho_appearance=0.4, psr=4.0))
    assert (d.case, d.status, d.rule) == (
        Case.CONTOUR,
        TargetStatus.TRACKING,
        Rule.CONTOUR_COLOUR_CHANGED,
    )
    assert not d.learn


def test_a_contour_without_the_filter_is_taken():
    d = decide(evidence(appearance_box=None, psr=NAN))
    assert (d.case, d.rule) == (Case.CONTOUR, Rule.CONTOUR) and d.learn


def test_strong_colour_elsewhere_overrides_an_unconfirmed_contour():
    d = decide(evidence(psr=4.0, meanshift_box=at(115), rho_meanshift=0.95))
    assert (d.case, d.rule, d.stage) == (Case.COLOUR, Rule.COLOUR_AGAINST_CONTOUR, "meanshift")
    assert (d.box.w, d.box.h) == SIZE and d.box.cx == 115  # at the mean shift, the usual size


def test_colour_carries_the_target_through_ir_clutter():
    d = decide(evidence(psr=3.0, contour_ok=False, contour_reason="too-large", rho_meanshift=0.9))
    assert (d.case, d.rule) == (Case.COLOUR, Rule.COLOUR_CONTOUR_FAILED)
    assert not d.learn and d.noise == 2.0


def test_colour_carries_the_target_through_thermal_crossover():
    d = decide(
        evidence(psr=3.0, contour_ok=False, contour_reason="low-contrast", rho_meanshift=0.8)
    )
    assert (d.case, d.rule) == (Case.COLOUR, Rule.COLOUR_IR_FADED)


def test_colour_that_clearly_matches_elsewhere_vetoes_contour_and_filter():
    """Two people alike in IR and in gradients, unlike in colour: both shape cues sit on the
    neighbour."""
    d = decide(
        evidence(rho_contour=0.3, rho_appearance=0.3, meanshift_box=at(112), rho_meanshift=0.95),
        CFG,
    )
    assert (d.case, d.box.cx) == (Case.COLOUR, 112)


def test_a_measurement_out_of_reach_is_not_taken():
    far = at(100 + 2 * SIZE[0])  # two widths from the prediction and from the last box
    d = decide(evidence(appearance_box=far, contour_box=far, meanshift_box=far))
    assert d.case == Case.COAST and not d.measured


def test_the_reach_grows_with_the_predictions_uncertainty():
    """30 px (1.5 widths) from the prediction and the last box: out of ``jump_fraction``'s reach
    while the motion is known (the prediction's deviation 2 px), within it while it is not (8 px:
    15 + 3 x 8 = 39 px)."""
    far = at(130)
    known = decide(
        evidence(appearance_box=far, contour_box=far, meanshift_box=far, prior_std_px=(2.0, 2.0)),
        CFG,
    )
    unknown = decide(
        evidence(appearance_box=far, contour_box=far, meanshift_box=far, prior_std_px=(8.0, 8.0)),
        CFG,
    )
    assert known.case == Case.COAST
    assert (unknown.case, unknown.box) == (Case.CONTOUR, far)
    assert (
        decide(
            evidence(
                appearance_box=far, contour_box=far, meanshift_box=far, prior_std_px=(8.0, 8.0)
            ),
            DeciderConfig(jump_sigma=0.0),
        ).case
        == Case.COAST
    )


def test_nothing_measured_coasts():
    d = decide(
        evidence(
            contour_box=None,
            contour_ok=False,
            contour_reason="no-component",
            rho_contour=NAN,
            appearance_box=None,
            psr=NAN,
            meanshift_box=at(101),
            rho_meanshift=0.2,
        ),
        CFG,
    )
    assert (d.case, d.status, d.rule, d.stage) == (
        Case.COAST,
        TargetStatus.OCCLUDED_SEVERE,
        Rule.NO_EVIDENCE,
        "kalman",
    )
    weak = decide(
        evidence(
            contour_box=None,
            contour_ok=False,
            contour_reason="no-component",
            rho_contour=NAN,
            psr=5.0,
            rho_meanshift=0.65,
        ),
        CFG,
    )
    assert (weak.case, weak.status, weak.rule) == (
        Case.COAST,
        TargetStatus.OCCLUDED_PARTIAL,
        Rule.PARTIAL_EVIDENCE,
    )


# ----------------------------------------------------------------------------------------- missing


def test_the_filter_takes_a_hidden_target_back_near_its_prediction():
    d = decide(missing(appearance_box=at(104), psr=12.0, rho_appearance=0.8))
    assert (d.case, d.status, d.rule, d.stage) == (
        Case.REACQUIRED,
        TargetStatus.TRACKING,
        Rule.APPEARANCE_NEAR_PREDICTION,
        "appearance",
    )
    assert not d.learn
    assert (
        decide(missing(appearance_box=at(104), psr=8.0)).case == Case.COAST
    )  # under psr_reacquire


def test_redetection_far_away_needs_the_colour_to_agree():
    far = at(250)
    ok = decide(missing(appearance_box=far, psr=12.0, rho_appearance=0.8, redetected=True))
    assert (ok.case, ok.rule) == (Case.REACQUIRED, Rule.REDETECTED)
    assert (
        decide(missing(appearance_box=far, psr=12.0, rho_appearance=0.4, redetected=True)).case
        == Case.COAST
    )
    assert (
        decide(missing(appearance_box=far, psr=12.0, rho_appearance=0.8)).case == Case.COAST
    )  # not searched


def test_a_find_far_away_yields_to_a_better_colour_match_near_the_prediction():
    """A hidden target whose mean shift near the prediction matches its colour at 0.85 is not
    taken to a look-alike 100 px away that the re-detection search found at 0.75 (the colour
    near the prediction takes it back there); a match near the prediction better by less than
    ``redetect_local_margin``, or the margin at 1, leaves the find its place."""
    ev = missing(
        14,
        appearance_box=at(200),
        psr=12.0,
        rho_appearance=0.75,
        redetected=True,
        meanshift_box=at(102),
        rho_meanshift=0.85,
    )
    d = decide(ev)
    assert (d.case, d.rule, d.box) == (Case.REACQUIRED, Rule.COLOUR_NEAR_PREDICTION, at(102))
    assert decide(dataclasses.replace(ev, rho_meanshift=0.78)).rule == Rule.REDETECTED
    assert decide(ev, DeciderConfig(redetect_local_margin=1.0)).rule == Rule.REDETECTED
    # a find near the prediction is no look-alike elsewhere: it is taken
    near = dataclasses.replace(ev, appearance_box=at(104))
    assert decide(near).rule in (Rule.REDETECTED, Rule.APPEARANCE_NEAR_PREDICTION)


def test_a_hidden_target_is_taken_back_where_its_speed_can_have_carried_it():
    """Last seen at x = 60, 3 frames ago, moving 10 px a frame: a confident detection at x = 85
    (15 px + 30 px of reach) is taken back though the prediction (x = 100) is 15 px off and the
    colour says little; at 3 px a frame, without ``reach_missing`` or from the re-detection
    search with a colour unlike the target's, it is not."""
    seen = dict(seen=(60.0, 100.0), seen_frames=3, speed_px=10.0)
    ev = missing(3, appearance_box=at(85), psr=12.0, rho_appearance=0.5, **seen)
    d = decide(ev)
    assert (d.case, d.rule, d.box) == (Case.REACQUIRED, Rule.APPEARANCE_NEAR_PREDICTION, at(85))
    assert decide(dataclasses.replace(ev, speed_px=3.0)).case == Case.COAST
    assert decide(ev, DeciderConfig(reach_missing=False)).case == Case.COAST
    assert decide(dataclasses.replace(ev, redetected=True)).rule == Rule.REDETECTED
    low = dataclasses.replace(ev, redetected=True, rho_appearance=0.2)
    assert decide(low).case == Case.COAST
    # a better colour match elsewhere vetoes it, as for a tracked target
    veto = dataclasses.replace(ev, rho_appearance=0.3, meanshift_box=at(140), rho_meanshift=0.8)
    assert decide(veto).case == Case.COAST


def test_the_reach_around_the_last_box_grows_with_the_targets_speed():
    """A tracked target 12 px wide moving 10 px a frame turns back: its filter detection 10 px
    behind its last box (and 20 px behind a prediction sure to 1 px) is within reach at
    ``jump_speed`` 1, not at 0."""
    size = (12.0, 30.0)
    ev = evidence(
        ref_size=size,
        prior=at(120, w=12, h=30),
        prior_std_px=(1.0, 1.0),
        last=at(110, w=12, h=30),
        appearance_box=at(100, w=12, h=30),
        contour_box=None,
        contour_ok=False,
        contour_reason="no-component",
        meanshift_box=at(100, w=12, h=30),
        speed_px=10.0,
    )
    assert decide(ev).rule == Rule.APPEARANCE_CONTOUR_FAILED
    assert decide(ev, DeciderConfig(jump_speed=0.0)).case == Case.COAST


def test_a_contour_near_the_prediction_takes_it_back_when_the_colour_agrees():
    d = decide(missing(contour_box=at(103), contour_ok=True, contour_reason="ok", rho_contour=0.8))
    assert (d.case, d.rule, d.stage) == (Case.REACQUIRED, Rule.CONTOUR_NEAR_PREDICTION, "levelset")
    assert (
        d.contour_scale and not d.learn
    )  # the first frame back measures the size, teaches nothing
    assert (
        decide(
            missing(contour_box=at(103), contour_ok=True, contour_reason="ok", rho_contour=0.5),
            CFG,
        ).case
        == Case.COAST
    )
    beside = decide(
        missing(
            frames=1, contour_box=at(125), contour_ok=True, contour_reason="ok", rho_contour=0.8
        ),
        CFG,
    )
    assert beside.case == Case.COAST  # outside the gate (half a size plus 1 px per missing frame)


def test_strong_colour_near_the_prediction_takes_it_back():
    d = decide(missing(meanshift_box=at(102), rho_meanshift=0.9))
    assert (d.case, d.rule) == (Case.REACQUIRED, Rule.COLOUR_NEAR_PREDICTION)


def test_lost_after_max_missing_frames_or_out_of_the_frame():
    d = decide(missing(frames=LIFE.max_missing_frames))
    assert (d.case, d.status, d.rule) == (
        Case.LOST,
        TargetStatus.LOST,
        Rule.MISSING_TOO_LONG,
    )
    assert decide(missing(frames=LIFE.max_missing_frames - 1)).case == Case.COAST
    out = decide(missing(frames=2, outside=True))
    assert (out.case, out.rule) == (Case.LOST, Rule.LEFT_THE_FRAME)


def test_a_lost_target_found_again_is_reacquired():
    d = decide(
        missing(frames=80, appearance_box=at(40), psr=15.0, rho_appearance=0.85, redetected=True),
        CFG,
    )
    assert d.case == Case.REACQUIRED


# ------------------------------------------------------------------------------------ modes, paper


def test_one_channel_modes_use_the_same_rules():
    """Visible only: no contour; IR only: the mean-shift histogram is IR intensity
    (colour_informative)."""
    vis = evidence(
        contour_box=None, contour_ok=False, contour_reason="no-contour", rho_contour=NAN
    )
    assert decide(vis).case == Case.APPEARANCE
    assert decide(dataclasses.replace(vis, psr=3.0)).case == Case.COLOUR
    ir = evidence(psr=3.0, contour_ok=False, contour_reason="leak", rho_meanshift=0.9)
    assert decide(ir).case == Case.COLOUR


NO_FILTER = dict(appearance_box=None, psr=NAN, rho_appearance=NAN)
"""The evidence of a tracker composed without the appearance cue: no filter detection."""


def test_without_the_filter_its_rules_never_apply():
    assert decide(evidence(**NO_FILTER)).rule == Rule.CONTOUR
    d = decide(evidence(contour_ok=False, contour_reason="leak", rho_meanshift=0.5, **NO_FILTER))
    assert d.case == Case.COAST
    assert decide(missing(**NO_FILTER)).case == Case.COAST


def test_without_contour_checks_any_contour_is_clean():
    leaking = dict(contour_ok=False, contour_reason="leak", contour_box=at(100, h=20))
    d = decide(evidence(contour_checked=False, **leaking, **NO_FILTER))
    assert (d.case, d.status) == (
        Case.CONTOUR,
        TargetStatus.TRACKING,
    )  # not even a cut contour is an occlusion


@pytest.mark.parametrize(
    "cls, name, value",
    [
        (DeciderConfig, "agree_fraction", 0.0),
        (DeciderConfig, "jump_fraction", 6.0),
        (DeciderConfig, "colour_veto_margin", 0.0),
        (SizeConfig, "scale_agree_ratio", 1.0),
        (DeciderConfig, "psr_confident", -1.0),
        (RedetectConfig, "every_frames", 0),
    ],
)
def test_declared_ranges_are_enforced(cls, name, value):
    with pytest.raises(ValueError, match=f"{cls.section}.{name}"):
        cls(**{name: value})


# ------------------------------------------------------------------------------------ the table


def test_the_why_text_is_made_from_the_rule_and_its_details():
    """``targets.csv``'s ``decision`` column: ``case:why``, the why from the rule's name."""
    d = decide(evidence(contour_ok=False, contour_reason="leak", contour_box=at(110, w=60)))
    assert d.text == "appearance:appearance-contour-leak"
    lost = decide(missing(frames=LIFE.max_missing_frames))
    assert lost.text == f"lost:{LIFE.max_missing_frames + 1}-frames-without-a-measurement"
    assert Rule.SPLIT_BLOB.text() == "split-blob" and Rule.MERGE_EQ11.text() == "eq11"


def test_every_rule_of_the_tables_is_reached():
    """Each rule of the two tables decides some evidence of this file (none is dead)."""
    cases = [
        evidence(),
        evidence(contour_box=at(111)),
        evidence(contour_ok=False, contour_reason="leak", contour_box=at(110, w=60)),
        evidence(psr=4.0, meanshift_box=at(115), rho_meanshift=0.95),
        evidence(rho_contour=0.4, rho_meanshift=0.45, rho_appearance=0.4, psr=4.0),
        evidence(**NO_FILTER),
        evidence(psr=3.0, contour_ok=False, contour_reason="too-large", rho_meanshift=0.9),
        evidence(psr=3.0, contour_ok=False, contour_reason="low-contrast", rho_meanshift=0.8),
        missing(appearance_box=at(250), psr=12.0, rho_appearance=0.8, redetected=True),
        missing(appearance_box=at(104), psr=12.0, rho_appearance=0.8),
        missing(
            appearance_box=at(200),
            psr=15.0,
            rho_appearance=0.3,
            meanshift_box=at(201),
            rho_meanshift=0.3,
        ),
        missing(contour_box=at(103), contour_ok=True, contour_reason="ok", rho_contour=0.8),
        missing(meanshift_box=at(102), rho_meanshift=0.9),
    ]
    reached = {decide(ev).rule for ev in cases}
    assert {r for r, _, _ in TRACKED + MISSING} <= reached


BG = dataclasses.replace(CFG, background_share=0.05)


def test_a_filter_box_on_the_background_is_not_confident_unless_the_colour_confirms_it():
    """The filter alone (the contour failed) on a box that differs from the still background in
    2 % of its pixels: without a colour match it coasts, partly seen; with one (a target that
    stood still long enough to enter the background) it is taken."""
    alone = dict(
        contour_ok=False, contour_reason="no-component", contour_box=None, rho_meanshift=0.2
    )
    d = decide(evidence(**alone, foreground_share=0.02, rho_appearance=0.1), BG)
    assert (d.case, d.status, d.rule) == (
        Case.COAST,
        TargetStatus.OCCLUDED_PARTIAL,
        Rule.ON_BACKGROUND,
    )
    assert not d.learn and d.box is None and d.text == "coast:filter-on-background"
    seen = decide(evidence(**alone, foreground_share=0.02, rho_appearance=0.9), BG)
    assert seen.rule == Rule.APPEARANCE_CONTOUR_FAILED and seen.learn
    on_target = decide(evidence(**alone, foreground_share=0.4, rho_appearance=0.1), BG)
    assert on_target.rule == Rule.APPEARANCE_CONTOUR_FAILED
    unknown = decide(evidence(**alone, foreground_share=NAN, rho_appearance=0.1), BG)
    assert unknown.rule == Rule.APPEARANCE_CONTOUR_FAILED  # no still background: no test
    off = dataclasses.replace(BG, background_share=0.0)
    assert decide(evidence(**alone, foreground_share=0.0, rho_appearance=0.1), off).measured


def test_a_hidden_target_is_not_taken_back_onto_the_background():
    ev = missing(appearance_box=at(104), psr=12.0, rho_appearance=0.3, foreground_share=0.0)
    assert decide(ev, BG).case == Case.COAST
    assert decide(dataclasses.replace(ev, foreground_share=0.5), BG).case == Case.REACQUIRED


def test_the_background_is_asked_only_where_nothing_else_confirms_the_filter():
    from pipeline.trackers.dual.decide import needs_background

    alone = dict(contour_ok=False, contour_reason="no-component", contour_box=None)
    assert needs_background(evidence(**alone, rho_appearance=0.1), BG)
    assert needs_background(evidence(**alone, colour_informative=False), BG)
    assert not needs_background(evidence(**alone, rho_appearance=0.9), BG)  # colour confirms
    assert not needs_background(evidence(rho_appearance=0.1), BG)  # a clean contour on it
    assert needs_background(evidence(contour_box=at(111), rho_appearance=0.1), BG)  # aside
    assert not needs_background(evidence(**alone, rho_appearance=0.1, psr=5.0), BG)
    assert not needs_background(
        evidence(**alone, rho_appearance=0.1), CFG.__class__(background_share=0.0)
    )


def test_a_target_the_visible_channel_alone_carries_is_not_refused_by_the_ir_background():
    """A target tracked without a break (measured cleanly on the frame before) whose filter
    peaks at PSR 20 in the visible channel and 3 in the IR, on a box that differs from the
    IR background in 2 % of its pixels and whose colour a shadow dimmed: the IR does not see
    it, so its background does not refuse it. Each condition, broken, brings the refusal
    back."""
    from pipeline.trackers.dual.decide import needs_background

    carried = dict(
        contour_ok=False,
        contour_reason="no-component",
        contour_box=None,
        rho_meanshift=0.2,
        rho_appearance=0.1,
        foreground_share=0.02,
        support=(20.0, 3.0),
        seen=(100.0, 100.0),
        seen_frames=1,
    )
    d = decide(evidence(**carried), BG)
    assert d.rule == Rule.APPEARANCE_CONTOUR_FAILED and d.measured and d.learn
    assert not needs_background(evidence(**carried), BG)  # nothing to ask it
    for change in (
        dict(seen_frames=2),  # a break since its last clean measurement
        dict(seen=None, seen_frames=0),  # none yet
        dict(support=(20.0, 9.0)),  # the IR sees it: its background can tell
        dict(support=(11.9, 3.0)),  # the visible peak under 12
    ):
        ev = evidence(**{**carried, **change})
        assert decide(ev, BG).rule == Rule.ON_BACKGROUND, change
    off = dataclasses.replace(BG, visible_carries_psr=0.0)
    assert decide(evidence(**carried), off).rule == Rule.ON_BACKGROUND
    found_again = missing(
        **{**carried, "appearance_box": at(104), "psr": 20.0, "meanshift_box": at(104)}
    )
    assert decide(found_again, BG).case == Case.COAST  # a gap: a look-alike is seen the same


def far_find(**kw) -> Evidence:
    """A target missing for 2 frames that its filter finds 60 px from its prediction at PSR 20
    (15 and 11 in the two channels), where the mean shift converged too (colour match 0.3);
    ``kw`` changes what a cue found."""
    base = dict(
        appearance_box=at(160),
        psr=20.0,
        rho_appearance=0.3,
        support=(15.0, 11.0),
        meanshift_box=at(162),
        rho_meanshift=0.32,
    )
    base.update(kw)
    return missing(2, **base)


def test_two_cues_that_agree_take_a_missing_target_back_far_from_its_prediction():
    """A fast target that turned while it coasted: the filter finds it 60 px from its prediction
    at PSR 20, confident in both channels (15 and 11), and the mean shift converged there too,
    though the colour matches at 0.3 only (a shadow dimmed it). Neither the prediction, the
    reach of its speed nor the colour's ``reacquire_rho`` takes it back; the agreement does
    (``APPEARANCE_AND_COLOUR``). Each of the other tests refuses it alone: the mean shift
    elsewhere, one channel's peak under ``psr_reacquire`` (a cold look-alike), another target's
    box on it, another target's colour model matching there better than its own, a box that is
    the still background, a PSR under ``corroborate_psr``, the rule off; with one channel, no
    still background to ask and no contour on the find (visible footage alone, where a look-alike
    fools the colour and the gradients of the one image)."""
    ev = far_find(seen=(100.0, 100.0), seen_frames=2, speed_px=3.0)
    d = decide(ev, BG)
    assert (d.case, d.rule, d.box, d.status) == (
        Case.REACQUIRED,
        Rule.APPEARANCE_AND_COLOUR,
        at(160),
        TargetStatus.TRACKING,
    )
    assert d.text == "re-acquired:appearance-and-colour" and not d.learn
    for change in (
        dict(meanshift_box=at(100)),
        dict(support=(15.0, 2.0)),
        dict(on_another=True),
        dict(rho_rival=0.5),
        dict(foreground_share=0.01),
        dict(psr=11.0),
    ):
        assert decide(dataclasses.replace(ev, **change), BG).case == Case.COAST, change
    assert decide(ev, dataclasses.replace(BG, corroborate_psr=0.0)).case == Case.COAST
    # one channel (infrared alone): the still background is the second check
    one = dataclasses.replace(ev, support=(NAN, 15.0), foreground_share=0.4)
    assert decide(one, BG).case == Case.REACQUIRED
    assert decide(dataclasses.replace(one, foreground_share=NAN), BG).case == Case.COAST
    # or a clean contour on the find (the background is not asked there)
    shaped = dataclasses.replace(
        one, foreground_share=NAN, contour_box=at(161), contour_ok=True, contour_reason="ok"
    )
    assert decide(shaped, BG).case == Case.REACQUIRED
    # both channels and no still background known (a moving camera): the channels suffice
    assert decide(dataclasses.replace(ev, foreground_share=NAN), BG).case == Case.REACQUIRED
    # a tracked target keeps its reach: the rule is for a missing one
    tracked = dataclasses.replace(ev, measured_last=True, missing=0, last=at(100))
    assert decide(tracked, BG).rule != Rule.APPEARANCE_AND_COLOUR


def test_a_corroborated_find_is_asked_whether_it_is_the_background_whatever_its_colour():
    """A far find that the colour matches at 0.9 would skip the background test as any filter
    detection the colour confirms; one that the agreement could take back is asked (a background
    structure in the target's colours), unless the mean shift is elsewhere."""
    from pipeline.trackers.dual.decide import needs_background

    ev = far_find(rho_appearance=0.9, rho_meanshift=0.9)
    assert needs_background(ev, BG)
    assert not needs_background(dataclasses.replace(ev, meanshift_box=at(100)), BG)
