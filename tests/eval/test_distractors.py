"""A track box on a distractor (a moving object that is not a target) is neither a TP nor an FP."""

from __future__ import annotations

import numpy as np

from pipeline.detect_run import score_frame
from pipeline.eval import evaluate
from pipeline.eval.mot import drop_distractor_matches
from pipeline.io.results import TrackTable
from pipeline.io.sequence import Truth
from pipeline.stages.detection import Detections, Region
from pipeline.types import BBox
from tests.eval.boxes import held

N = 4


def _const(box, frames=None):
    return held(box, N, frames)


def test_only_the_boxes_assigned_to_a_distractor_are_dropped():
    gt = {1: _const([0, 0, 10, 10])}
    car = {1001: _const([50, 50, 20, 10], frames=[1, 2])}
    tracks = {1: _const([1, 0, 10, 10]), 2: _const([51, 50, 20, 10]), 3: _const([52, 50, 4, 4])}
    out = drop_distractor_matches(gt, tracks, car)
    np.testing.assert_array_equal(out[1], tracks[1])
    assert (
        np.isnan(out[2][[1, 2]]).all() and not np.isnan(out[2][[0, 3]]).any()
    )  # only where the car is
    np.testing.assert_array_equal(
        out[3], tracks[3]
    )  # IoU 0.08 with the car: still a false positive
    assert not np.isnan(tracks[2]).any()  # the input is not modified


def test_a_box_on_both_goes_to_the_assignment_that_covers_more():
    gt = {1: _const([0, 0, 10, 10])}
    other = {1001: _const([2, 0, 10, 10])}
    tracks = {7: _const([0, 0, 10, 10]), 8: _const([2, 0, 10, 10])}
    out = drop_distractor_matches(gt, tracks, other)
    assert not np.isnan(out[7]).any() and np.isnan(out[8]).all()


def test_evaluate_counts_no_false_positive_on_a_distractor():
    gt = {1: _const([0, 0, 10, 10])}
    car = {1001: _const([50, 50, 20, 10])}
    tracks = TrackTable({1: _const([0, 0, 10, 10]), 2: _const([50, 50, 20, 10])}, {})
    with_d = evaluate(Truth({"visible": gt}, {}, {}, True, car), tracks, N)
    without = evaluate(Truth({"visible": gt}, {}, {}, True), tracks, N)
    assert without["false_positives"] == N and with_d["false_positives"] == 0
    assert with_d["mota"] == 1.0 and with_d["idf1"] == 1.0 and without["idf1"] < 1.0


def _region(cx, cy):
    return Region(
        BBox(cx - 2, cy - 2, 4, 4), (cx, cy), 16.0, 16, 1.0, 1.0, 1.0, np.zeros((0, 2), np.float32)
    )


def test_detection_scores_leave_out_rois_on_distractors_and_targets_they_overlap():
    boxes = [np.array([0, 0, 10, 10.0]), np.array([100, 0, 10, 10.0])]
    car = [np.array([50, 50, 20, 10.0]), np.array([105, 5, 20, 10.0])]
    empty = np.zeros((1, 1))
    d = Detections((_region(5, 5), _region(60, 55), _region(200, 200)), (), empty, empty)
    want, found, rois, correct = score_frame(d, boxes, [True, True], car)
    assert (want, found) == (1, 1)  # the second target is overlapped by a distractor: not isolated
    assert (rois, correct) == (
        2,
        1,
    )  # the ROI on the car is not counted; the one on nothing is wrong
