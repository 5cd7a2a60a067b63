"""Members placed inside one blob: planted textured targets recovered to the pixel, and the rules
that leave a member unplaced (look-alikes, a blob the size of one target, outside the gate)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pipeline.stages.blob import Member, place_members, template_patch
from pipeline.tracker_config import DetectConfig
from pipeline.types import BBox

WIDE = np.diag([400.0, 400.0])  # a loose motion gate (20 px standard deviation)


def _texture(seed: int, h: int, w: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = cv2.GaussianBlur(rng.normal(128, 50, (h, w)).astype(np.float32), (0, 0), 1.5)
    return np.clip(t, 0, 255)


def _scene(pieces: list[tuple[np.ndarray, int, int]]) -> np.ndarray:
    """A flat 120 x 160 frame with each (texture, x, y) pasted at its top-left corner."""
    frame = np.full((120, 160), 40.0, np.float32)
    for tex, x, y in pieces:
        h, w = tex.shape
        frame[y : y + h, x : x + w] = tex
    return frame


def test_two_textured_targets_in_one_blob_are_both_found_where_planted():
    a, b = _texture(1, 30, 14), _texture(2, 30, 14)
    frame = _scene([(a, 50, 40), (b, 66, 42)])  # side by side, 2 px apart: one blob
    blob = BBox(50, 40, 30, 32)
    members = [
        Member(a, (50 + 7 + 3.0, 40 + 15 - 2.0), WIDE),  # predictions a few px off
        Member(b, (66 + 7 - 3.0, 42 + 15 + 2.0), WIDE),
    ]
    got = place_members(frame, blob, members, gate_chi2=13.8, min_correlation=0.5)
    assert got[0] is not None and got[1] is not None
    assert (got[0].box.x, got[0].box.y) == (50, 40)
    assert (got[1].box.x, got[1].box.y) == (66, 42)
    assert (got[0].box.w, got[0].box.h) == (14, 30)  # the template's size
    assert got[0].correlation > 0.99 and got[1].correlation > 0.99


def _both_at_one_prediction(frame, blob, first, second):
    """Two members predicted at one point (57, 55), placed without the look-alike margin."""
    members = [Member(first, (57.0, 55.0), WIDE), Member(second, (57.0, 55.0), WIDE)]
    return place_members(frame, blob, members, gate_chi2=13.8, min_correlation=0.3, margin=0.0)


def test_the_joint_choice_does_not_give_one_place_to_both():
    """Two members whose templates both match one target best: the better match takes it and
    the other is placed elsewhere or nowhere, never on the same object."""
    a = _texture(3, 30, 14)
    near_a = np.clip(a + _texture(4, 30, 14) * 0.6 - 77, 0, 255)  # a's look-alike, noisier
    frame = _scene([(a, 50, 40), (_texture(5, 30, 14), 66, 40)])
    blob = BBox(50, 40, 30, 30)
    got = _both_at_one_prediction(frame, blob, a, near_a)
    assert got[0] is not None and (got[0].box.x, got[0].box.y) == (50, 40)
    assert got[1] is None or got[1].box.iou(got[0].box) <= 0.5


def test_look_alikes_are_left_to_their_motion():
    """Two members with the same template cannot be told apart inside their blob: neither is
    placed (the margin), whereas distinct ones are."""
    a = _texture(6, 30, 14)
    frame = _scene([(a, 50, 40), (a, 66, 40)])
    blob = BBox(50, 40, 30, 30)
    same = [Member(a, (57.0, 55.0), WIDE), Member(a, (73.0, 55.0), WIDE)]
    assert place_members(frame, blob, same, gate_chi2=13.8, min_correlation=0.5) == [None, None]
    b = _texture(9, 30, 14)
    frame = _scene([(a, 50, 40), (b, 66, 40)])
    distinct = [Member(a, (57.0, 55.0), WIDE), Member(b, (73.0, 55.0), WIDE)]
    placed = place_members(frame, blob, distinct, gate_chi2=13.8, min_correlation=0.5)
    assert [(p.box.x, p.box.y) for p in placed if p is not None] == [(50, 40), (66, 40)]


def test_a_blob_the_size_of_one_target_holds_one():
    """A second track in a blob that one target fills is a duplicate: only the better match
    is placed (``max_fill``)."""
    a = _texture(7, 30, 14)
    frame = _scene([(a, 50, 40)])
    blob = BBox(50, 40, 14, 30)
    shifted = np.roll(a, 2, axis=1)  # a duplicate's template, taken 2 px off
    got = _both_at_one_prediction(frame, blob, a, shifted)
    assert got[0] is not None and got[1] is None


def test_a_place_beyond_the_motion_gate_is_not_taken():
    a = _texture(8, 30, 14)
    frame = _scene([(a, 50, 40)])
    blob = BBox(40, 30, 60, 50)
    tight = np.diag([4.0, 4.0])  # 2 px standard deviation
    far = Member(a, (57.0 + 12, 55.0), tight)  # predicted 12 px right of it: gamma 36
    assert place_members(frame, blob, [far], gate_chi2=13.8, min_correlation=0.5) == [None]
    near = Member(a, (57.0 + 3, 55.0), tight)
    (p,) = place_members(frame, blob, [near], gate_chi2=13.8, min_correlation=0.5)
    assert p is not None and (p.box.x, p.box.y) == (50, 40)


@pytest.mark.parametrize(
    ("box", "shape"),
    [
        (BBox(10.4, 5.6, 20, 10), (10, 20)),
        (BBox(-5, -5, 12, 12), (7, 7)),
        (BBox(157, 0, 9, 9), None),
    ],
)
def test_template_patch_rounds_and_clips(box, shape):
    frame = np.arange(120 * 160, dtype=np.float32).reshape(120, 160)
    p = template_patch(frame, box)
    if shape is None:
        assert p is None  # under 4 px left inside the frame
    else:
        assert p is not None and p.shape == shape and p.dtype == np.float32
        assert p[0, 0] == frame[max(0, round(box.y)), max(0, round(box.x))]


def test_the_detection_tracker_places_members_by_default():
    a = DetectConfig().association
    assert a.place_in_blobs is True and a.blob_min_correlation == 0.5
    assert a.blob_reach_fraction == 0.25 and a.blob_motion_weight == 0.036


def test_the_motion_picks_the_nearer_of_two_equal_matches():
    """Two places match the template equally: the one nearer the prediction is worth more
    (``motion_weight``); without it the choice is the correlation's alone."""
    a = _texture(10, 30, 14)
    frame = _scene([(a, 40, 40), (a, 90, 40)])
    blob = BBox(30, 30, 90, 50)
    m = Member(a, (90 + 7 - 4.0, 55.0), np.diag([900.0, 900.0]))  # 4 px left of the right one
    (p,) = place_members(
        frame, blob, [m], gate_chi2=13.8, min_correlation=0.5, motion_weight=0.036
    )
    assert p is not None and (p.box.x, p.box.y) == (90, 40)
    m = Member(a, (40 + 7 + 4.0, 55.0), np.diag([900.0, 900.0]))  # 4 px right of the left one
    (p,) = place_members(
        frame, blob, [m], gate_chi2=13.8, min_correlation=0.5, motion_weight=0.036
    )
    assert p is not None and (p.box.x, p.box.y) == (40, 40)


def test_a_place_beyond_the_reach_is_not_taken():
    """``reach`` bounds the distance as a share of the template's width and height, whatever
    the gate allows."""
    a = _texture(11, 30, 14)
    frame = _scene([(a, 50, 40)])
    blob = BBox(40, 30, 60, 50)
    loose = np.diag([900.0, 900.0])
    far = Member(a, (57.0 + 6, 55.0), loose, reach=0.25)  # 6 px across, 3.5 allowed
    assert place_members(frame, blob, [far], gate_chi2=13.8, min_correlation=0.5) == [None]
    tall = Member(a, (57.0, 55.0 + 6), loose, reach=0.25)  # 6 px down, 7.5 allowed
    (p,) = place_members(frame, blob, [tall], gate_chi2=13.8, min_correlation=0.5)
    assert p is not None and (p.box.x, p.box.y) == (50, 40)


def test_a_crowd_in_one_blob_is_placed_greedily_and_each_where_planted():
    """Twelve members in one blob (5 ** 12 combinations of their candidates): the greedy choice
    takes over from the joint one and still finds every member where it was planted."""
    frame = np.full((100, 300), 40.0, np.float32)
    members, xs = [], [10 + 23 * k for k in range(12)]
    for k, x in enumerate(xs):
        tex = _texture(100 + k, 30, 14)
        frame[30:60, x : x + 14] = tex
        members.append(Member(tex, (x + 7 + 1.0, 45.0 - 1.0), WIDE, reach=0.5))
    blob = BBox(10, 30, 23 * 11 + 14, 30)
    got = place_members(frame, blob, members, gate_chi2=13.8, min_correlation=0.5)
    assert [(p.box.x, p.box.y) for p in got if p is not None] == [(x, 30) for x in xs]
