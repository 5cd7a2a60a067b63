"""BBox geometry: the one convention, exact on hand-computed cases."""

import math

import numpy as np
import pytest

from pipeline.types import BBox, TargetStatus


def test_center_and_corners():
    b = BBox(10, 20, 30, 40)
    assert b.center == (25.0, 40.0)
    assert (b.x2, b.y2) == (40.0, 60.0)
    assert BBox.from_corners(10, 20, 40, 60) == b
    assert BBox.from_center(25, 40, 30, 40) == b


def test_iou_exact():
    a, b = BBox(0, 0, 10, 10), BBox(5, 0, 10, 10)
    assert a.iou(b) == pytest.approx(50 / 150)
    assert a.iou(BBox(20, 20, 5, 5)) == 0.0
    assert a.iou(a) == 1.0


def test_clip_and_validity():
    assert BBox(-5, -5, 10, 10).clip(100, 100) == BBox(0, 0, 5, 5)
    assert BBox(200, 0, 10, 10).clip(100, 100).area == 0
    assert not BBox(0, 0, 0, 10).is_valid()
    assert not BBox(math.nan, 0, 1, 1).is_valid()


def test_to_cv_stays_inside():
    assert BBox(-3.4, 2.6, 10.2, 500).to_cv(100, 50) == (0, 3, 10, 47)


def test_statuses_are_design_names():
    assert [s.value for s in TargetStatus] == [
        "tentative",
        "tracking",
        "occluded-partial",
        "occluded-severe",
        "merged",
        "lost",
    ]
    assert not TargetStatus.LOST.is_reported and TargetStatus.MERGED.is_reported


def test_a_box_unpacks_and_becomes_an_array():
    b = BBox(1.5, 2.0, 3.0, 4.0)
    x, y, w, h = b
    assert (x, y, w, h) == (1.5, 2.0, 3.0, 4.0) and list(b) == [1.5, 2.0, 3.0, 4.0]
    a = np.asarray(b)
    assert a.dtype == np.float64 and a.tolist() == [1.5, 2.0, 3.0, 4.0]
    assert np.asarray([b, b]).shape == (2, 4)
