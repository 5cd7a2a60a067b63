"""The frame-level rule that gives one object to one target (``Decider.shared``,
``owner_of``, ``yields``)."""

from __future__ import annotations

import math

from pipeline.tracker_config import DeciderConfig
from pipeline.trackers.dual.decide import Case, Decider, Rule
from pipeline.types import BBox, TargetStatus

ON = Decider(DeciderConfig(shared_iou=0.5))


def test_two_measurements_are_one_object_from_the_configured_overlap():
    a = BBox(0, 0, 20, 40)
    assert ON.shared(a, BBox(4, 0, 20, 40))  # IoU 16/24 = 0.667
    assert not ON.shared(a, BBox(8, 0, 20, 40))  # IoU 12/28 = 0.43
    assert not ON.shared(a, None)
    assert not Decider(DeciderConfig()).shared(a, a)  # off by default: both take it


def test_the_target_that_held_the_object_keeps_it_against_one_coming_back_to_it():
    assert ON.owner_of((0.6, 0.95), (1.0, 0.0), held=(True, False)) == 0
    assert ON.owner_of((0.95, 0.6), (0.0, 1.0), held=(False, True)) == 1


def test_the_better_colour_match_owns_the_object_else_the_nearer_prediction():
    assert ON.owner_of((0.95, 0.70), (2.0, 0.0)) == 0  # colour decides, whatever the motion
    assert ON.owner_of((0.70, 0.95), (0.0, 2.0)) == 1
    assert ON.owner_of((0.90, 0.93), (0.1, 0.4)) == 0  # within the margin: the motion
    assert ON.owner_of((math.nan, 0.93), (0.6, 0.4)) == 1  # no colour: the motion


def test_the_target_that_yields_is_merged_on_the_object_or_hidden_and_learns_nothing():
    box, prior = BBox(100, 50, 20, 40), BBox(102, 50, 20, 40)
    on_it = ON.yields(3, box, prior)
    assert (on_it.case, on_it.rule) == (Case.SHARED, Rule.SHARED)
    assert on_it.status == TargetStatus.MERGED
    # it keeps to its own motion: its prediction is its measurement (not the other's box)
    assert on_it.box == prior and not on_it.learn and on_it.why == "measurement-taken-by-T3"
    elsewhere = ON.yields(3, box, BBox(140, 50, 20, 40))
    assert (elsewhere.case, elsewhere.status) == (Case.COAST, TargetStatus.OCCLUDED_PARTIAL)
    assert elsewhere.box is None and not elsewhere.learn


DENY = Decider(DeciderConfig(colour_deny_rho=0.35, inside_fraction=0.6))


def test_a_measurement_inside_another_target_with_the_wrong_colour_lies_on_it():
    small, big = BBox(110, 60, 20, 20), BBox(100, 40, 40, 80)  # wholly inside
    assert DENY.on_other(small, big, 0.10)
    assert not DENY.on_other(small, big, 0.50)  # its own colour: a target in front of another
    assert not DENY.on_other(small, big, math.nan)  # no colour to ask
    half = BBox(130, 60, 20, 20)  # 10 of 20 px wide inside: 0.5 of its area < 0.6
    assert not DENY.on_other(half, big, 0.10)
    assert DENY.on_other(BBox(126, 60, 20, 20), big, 0.10)  # 14 of 20: 0.7
    assert not Decider(DeciderConfig(colour_deny_rho=0.0)).on_other(small, big, 0.0)  # 0: off


def test_whether_the_yielding_target_stays_on_the_object_can_be_given():
    box = BBox(100, 50, 20, 40)
    far = BBox(300, 50, 20, 40)
    assert DENY.yields(2, box, far, on_object=True).status == TargetStatus.MERGED
    assert DENY.yields(2, box, box, on_object=False).case == Case.COAST
