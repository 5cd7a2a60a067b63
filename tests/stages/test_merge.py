"""Merge/split decisions of the dual tracker (paper §2.3, eq. 10-11) on hand-built boxes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.stages.merge import (
    associate,
    association_cost,
    choose_foreground,
    choose_foreground_stable,
    eq11,
    inside_blob,
    kmeans_shares,
    lookalike_sets,
    merge_groups,
    merge_test,
)
from pipeline.types import BBox


def box(cx: float, cy: float, w: float = 20, h: float = 40) -> BBox:
    return BBox.from_center(cx, cy, w, h)


def test_merge_test_eq10_two_boxes_approaching_overlapping_separating():
    a = box(100, 100)
    # approaching from the right: the test holds once the centres are closer than the half-widths'
    # sum (20 px)
    verdicts = [merge_test(a, box(100 + d, 100)) for d in (40, 25, 20.5, 19.5, 10, 0)]
    assert verdicts == [False, False, False, True, True, True]
    # separating again, on the other side
    assert [merge_test(a, box(100 - d, 100)) for d in (10, 19.5, 20.5)] == [True, True, False]
    # rows count too: side by side in x but one above the other by more than the half-heights' sum
    # (40 px)
    assert merge_test(a, box(105, 139))
    assert not merge_test(a, box(105, 141))
    # different sizes: the sum of the two half-sizes
    assert merge_test(box(0, 0, 10, 10), box(29, 0, 50, 10))
    assert not merge_test(box(0, 0, 10, 10), box(31, 0, 50, 10))


def test_merge_groups_joins_chains_of_pairs():
    boxes = {
        1: box(100, 100),
        2: box(115, 100),
        3: box(130, 100),
        4: box(300, 100),
        5: box(400, 100),
        6: box(410, 100),
    }
    assert merge_groups(boxes) == [(1, 2, 3), (5, 6)]  # 1-3 are linked only through 2
    assert merge_groups({1: box(0, 0)}) == []
    assert merge_groups({}) == []


def test_just_split_pairs_need_a_deeper_overlap_to_merge_again():
    a, b = box(100, 100), box(118, 100)  # 20-px-wide boxes 18 px apart: eq. 10 holds, barely
    assert merge_groups({1: a, 2: b}) == [(1, 2)]
    assert merge_groups({1: a, 2: b}, strict={2}, strict_scale=0.8) == []  # 18 >= 0.8 x 20
    assert merge_groups({1: a, 2: box(115, 100)}, strict={2}, strict_scale=0.8) == [
        (1, 2)
    ]  # 15 < 16


def test_foreground_is_the_best_colour_match_with_hysteresis():
    assert choose_foreground({1: 0.7, 2: 0.9}) == 2
    assert (
        choose_foreground({1: math.nan, 2: math.nan}, {1: 3.0, 2: 1.0}) == 2
    )  # no colour: nearest the blob
    assert choose_foreground({1: 0.7, 2: math.nan}) == 1
    # the previous foreground keeps its role unless beaten by more than the margin
    assert choose_foreground_stable({1: 0.90, 2: 0.93}, previous=1, margin=0.05) == 1
    assert choose_foreground_stable({1: 0.90, 2: 0.96}, previous=1, margin=0.05) == 2
    assert choose_foreground_stable({1: 0.90, 2: 0.93}, previous=None, margin=0.05) == 2


def test_inside_blob_moves_a_box_the_least_distance_into_the_blob():
    blob = BBox(100.0, 50.0, 60.0, 80.0)  # x 100..160, y 50..130
    assert inside_blob((130.0, 90.0), (20.0, 40.0), blob) == (
        130.0,
        90.0,
    )  # already inside: unchanged
    assert inside_blob((95.0, 90.0), (20.0, 40.0), blob) == (
        110.0,
        90.0,
    )  # sticks out left: left edges meet
    assert inside_blob((158.0, 125.0), (20.0, 40.0), blob) == (150.0, 110.0)  # out right and below
    assert inside_blob((95.0, 90.0), (70.0, 40.0), blob) == (
        130.0,
        90.0,
    )  # wider than the blob: its centre


def test_eq11_mirrors_the_foreground_about_the_merged_centre():
    assert eq11((100.0, 50.0), (90.0, 52.0)) == (110.0, 48.0)
    assert eq11((100.0, 50.0), (100.0, 50.0)) == (100.0, 50.0)


def test_reassociation_is_global_not_greedy():
    # greedy on target 0 would take blob 0 (cost 0.1) and leave target 1 with 0.9; the optimum
    # swaps
    cost = np.array([[0.1, 0.2], [0.15, 0.9]])
    assert sorted(associate(cost)) == [(0, 1), (1, 0)]
    assert associate(np.zeros((0, 3))) == []
    assert associate(np.zeros((2, 0))) == []
    # more blobs than targets: every target gets one
    assert sorted(associate(np.array([[0.5, 0.1, 0.9]]))) == [(0, 1)]


def test_association_cost_adds_distance_in_target_sizes_and_treats_missing_colour_as_neutral():
    rho = np.array([[0.9, np.nan]])
    d = np.array([[10.0, 30.0]])
    c = association_cost(rho, d, np.array([20.0]), motion_weight=1.0)
    np.testing.assert_allclose(c, [[0.1 + 0.5, 0.5 + 1.5]])
    # look-alikes: equal colour, the distance decides
    c = association_cost(
        np.array([[0.95, 0.95], [0.95, 0.95]]),
        np.array([[2.0, 30.0], [28.0, 3.0]]),
        np.array([40.0, 40.0]),
        1.0,
    )
    assert sorted(associate(c)) == [(0, 0), (1, 1)]


def test_kmeans_recovers_two_side_by_side_bodies():
    # two 10x30 bodies overlapping by 4 px, as one merged blob; predictions 6 px off towards each
    # other
    mask = np.zeros((60, 60), bool)
    mask[10:40, 10:20] = True
    mask[12:42, 16:26] = True
    cents = kmeans_shares(
        mask, (100, 200), [(118.0, 225.0), (118.5, 227.0)], [(10.0, 30.0), (10.0, 30.0)]
    )
    (x1, y1), (x2, y2) = cents
    assert x1 == pytest.approx(114.3, abs=1.0) and x2 == pytest.approx(121.7, abs=1.0)
    assert y1 == pytest.approx(225.5, abs=1.5) and y2 == pytest.approx(227.5, abs=1.5)
    assert kmeans_shares(np.zeros((5, 5), bool), (0, 0), [(1.0, 1.0)], [(2.0, 2.0)]) == [None]


def test_lookalike_sets_from_model_similarity():
    red = np.array([0.8, 0.2, 0.0, 0.0])
    red2 = np.array([0.75, 0.25, 0.0, 0.0])
    green = np.array([0.0, 0.0, 0.9, 0.1])
    assert lookalike_sets({1: red, 2: green, 3: red2}, 0.85) == [(1, 3)]
    assert lookalike_sets({1: red, 2: green}, 0.85) == []
