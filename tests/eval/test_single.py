"""Single-target metrics against hand-computed values and a plain-loop reference."""

import math

import numpy as np
import pytest

from pipeline.eval import evaluate
from pipeline.eval.single import (
    center_errors,
    ious,
    precision_curve,
    single_target_metrics,
    success_curve,
)
from pipeline.io.results import TrackTable
from pipeline.io.sequence import Truth

NAN = [math.nan] * 4


def test_hand_computed_fixture():
    gt = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10], NAN, [0, 0, 10, 10]], float)
    pred = np.array([[0, 0, 10, 10], [3, 4, 10, 10], [20, 0, 10, 10], [5, 5, 5, 5], NAN], float)
    err = center_errors(pred, gt)
    np.testing.assert_allclose(err[:3], [0, 5, 20])
    assert math.isnan(err[3]) and math.isinf(err[4])
    ov = ious(pred, gt)
    np.testing.assert_allclose(ov[[0, 1, 2, 4]], [1.0, 42 / 158, 0.0, 0.0])
    m = single_target_metrics(pred, gt)
    assert m["frames"] == 4 and m["frames_without_output"] == 1
    assert m["p5"] == 0.5  # errors 0 and 5 (inclusive) of 4 frames
    assert m["p20"] == 0.75  # 20 is inclusive
    assert m["mean_error_px"] == pytest.approx((0 + 5 + 20) / 3)
    # success: frame 0 (IoU 1) counts for t < 1; frame 1 (0.2658) for t in {0, .05, ..., .25}; t=1
    # never
    assert m["auc"] == pytest.approx((20 * 1 + 6 * 1) / 4 / 21)


def _reference(pred, gt):
    """Independent plain-loop computation of p20 and AUC (default protocol)."""
    errs, ovs = [], []
    for p, g in zip(pred, gt, strict=True):
        if any(math.isnan(v) for v in g):
            continue
        if any(math.isnan(v) for v in p):
            errs.append(math.inf)
            ovs.append(0.0)
            continue
        errs.append(
            math.dist((p[0] + p[2] / 2, p[1] + p[3] / 2), (g[0] + g[2] / 2, g[1] + g[3] / 2))
        )
        iw = max(0.0, min(p[0] + p[2], g[0] + g[2]) - max(p[0], g[0]))
        ih = max(0.0, min(p[1] + p[3], g[1] + g[3]) - max(p[1], g[1]))
        inter = iw * ih
        ovs.append(inter / (p[2] * p[3] + g[2] * g[3] - inter))
    p20 = sum(e <= 20 for e in errs) / len(errs)
    auc = sum(sum(o > t / 20 for o in ovs) / len(ovs) for t in range(21)) / 21
    return p20, auc


def test_random_against_reference():
    rng = np.random.default_rng(3)
    gt = np.column_stack(
        [
            rng.uniform(0, 200, 300),
            rng.uniform(0, 200, 300),
            rng.uniform(10, 60, 300),
            rng.uniform(10, 60, 300),
        ]
    )
    pred = gt + rng.normal(0, 12, gt.shape)
    pred[:, 2:] = np.abs(pred[:, 2:]) + 1
    gt[::17] = np.nan
    pred[::23] = np.nan
    m = single_target_metrics(pred, gt)
    p20, auc = _reference(pred, gt)
    assert m["p20"] == pytest.approx(p20, abs=1e-12) and m["auc"] == pytest.approx(auc, abs=1e-12)


def test_curves_monotone():
    err = np.array([0, 3, 7, 40, np.inf, np.nan])
    pc = precision_curve(err)
    assert pc.shape == (51,) and np.all(np.diff(pc) >= 0) and pc[0] == 0.2 and pc[50] == 0.8
    sc = success_curve(np.array([0.0, 0.5, 1.0, np.nan]))
    assert sc[0] == pytest.approx(2 / 3) and sc[-1] == 0.0


def test_mpr_msr_take_the_better_channel():
    gv = np.array([[0, 0, 10, 10]], float)
    gi = np.array([[4, 0, 10, 10]], float)
    pred = np.array([[4, 0, 10, 10]], float)
    m = single_target_metrics(pred, gv, gi)
    assert m["p5"] == 1.0 and m["mpr"] == 1.0 and m["msr"] == pytest.approx(20 / 21)


def test_evaluate_object_keys():
    gt = np.array([[0, 0, 10, 10]] * 3, float)
    truth = Truth({"visible": {1: gt}, "infrared": {1: gt}})
    out = evaluate(truth, TrackTable({1: gt.copy()}, {}), 3)
    for k in ("p5", "p20", "auc", "mean_error_px", "npr", "mpr", "msr", "targets"):
        assert k in out
    assert out["p20"] == 1.0 and out["targets"]["1"]["auc"] == pytest.approx(20 / 21)
    assert "mota" not in out  # one target: no MOT keys


def test_evaluate_many_targets_with_no_track_at_all():
    """A detector that found nothing: every identity score is 0, nothing is left out."""
    gt = np.array([[0, 0, 10, 10]] * 3, float)
    truth = Truth({"infrared": {1: gt, 2: gt + 20}})
    out = evaluate(truth, TrackTable({}, {}), 3)
    assert out["idf1"] == out["idp"] == out["idr"] == 0.0
    assert out["p20"] == 0.0 and out["mota"] == 0.0


def test_a_one_based_results_file_is_read_as_one(tmp_path):
    """OTB's own truth file (1-based) scored against its sequence: 1.41 px off when read as
    0-based, exact with ``results_base=1`` (``evaluate --results-base 1``)."""
    from pipeline.eval import evaluate_files
    from tests.conftest import write_boxes, write_frames

    root = tmp_path / "otb"
    write_frames(root / "img", 5, name="{:04d}")
    write_boxes(root / "groundtruth_rect.txt", 5, sep="\t", base=1.0)
    as_zero = evaluate_files(root, root / "groundtruth_rect.txt")
    exact = evaluate_files(root, root / "groundtruth_rect.txt", results_base=1)
    assert as_zero["mean_error_px"] == pytest.approx(2**0.5)
    assert exact["mean_error_px"] == 0.0 and exact["p5"] == 1.0


def test_frame_truth_equals_the_sequence_scores_to_the_last_bit():
    """The per-frame scores the recording and the CSV stream (computed in Python floats) equal
    ``center_errors`` and ``ious`` on the same boxes, bit for bit: overlapping, touching,
    disjoint, identical and nested boxes, and a target not reported (inf, 0)."""
    from pipeline.eval import frame_truth
    from pipeline.eval.single import center_errors, ious
    from pipeline.types import BBox, FrameResult, TargetResult, TargetStatus

    rng = np.random.default_rng(5)
    gt = rng.uniform(0, 200, (300, 4))
    gt[:, 2:] = rng.uniform(1, 80, (300, 2))
    pred = gt + rng.normal(0, 15, (300, 4))
    pred[:, 2:] = np.abs(pred[:, 2:]) + 0.5
    pred[::10] = gt[::10]  # identical
    pred[5::10, 0] = gt[5::10, 0] + gt[5::10, 2]  # touching on the right
    pred[7::10, 0] = gt[7::10, 0] + 500  # disjoint
    truth = Truth({"infrared": {1: gt}}, {}, {}, False)
    for i in range(300):
        status = TargetStatus.LOST if i % 13 == 0 else TargetStatus.TRACKING
        r = FrameResult(i + 1, (TargetResult(1, BBox(*pred[i]), status, "x"),))
        ft = frame_truth(truth, r)
        p = pred[i : i + 1] if status.is_reported else np.full((1, 4), np.nan)
        assert ft.center_error_px[1] == center_errors(p, gt[i : i + 1])[0]
        assert ft.iou[1] == ious(p, gt[i : i + 1])[0]
