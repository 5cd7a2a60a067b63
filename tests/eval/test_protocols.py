"""The toolkits' rules: GTOT pooled strict precision and auc.m, LasHeR invalid frames, RGBT234
MPR/MSR."""

import math

import numpy as np
import pytest

from pipeline.eval import protocols

NAN = [math.nan] * 4


def test_gtot_strict_threshold_and_auc_m():
    gt = np.array([[0, 0, 10, 10]] * 4, float)
    pred = gt.copy()
    pred[1, 0] += 5  # exactly 5 px: not a hit with GTOT's strict '<'
    pred[2, 0] += 4
    pred[3] = [100, 100, 10, 10]
    r = protocols.gtot(pred, gt, gt)
    assert r["mpr"] == pytest.approx(2 / 4)
    # success per frame: IoU 1, 5/15, 6/14, 0; auc.m = trapezoid of the 51-point curve
    ious = np.array([1.0, 50 / 150, 60 / 140, 0.0])
    thr = np.arange(51) * 0.02
    curve = np.array([(ious > t).mean() for t in thr])
    expect = np.sum(
        (curve[1:] + curve[:-1]) / 2 * 0.02
    )  # x2=[thr,1], y2=[curve,1]: last interval has width 0
    assert r["msr"] == pytest.approx(expect)


def test_gtot_pools_frames_across_sequences():
    a = protocols.gtot_counts(
        np.array([[0, 0, 10, 10]] * 3, float), np.array([[0, 0, 10, 10]] * 3, float), None
    )
    b = protocols.gtot_counts(
        np.array([[50, 0, 10, 10]], float), np.array([[0, 0, 10, 10]], float), None
    )
    pooled = protocols.gtot_from_counts(
        a["frames"] + b["frames"],
        list(np.add(a["precision_counts"], b["precision_counts"])),
        list(np.add(a["success_counts"], b["success_counts"])),
    )
    assert pooled["mpr"] == pytest.approx(3 / 4)  # not the mean of per-sequence 1.0 and 0.0


def test_lasher_rules():
    gt = np.array(
        [[10, 10, 10, 10], [10, 10, 10, 10], NAN, [0, 10, 10, 10], [10, 10, 10, 10]], float
    )
    pred = np.array(
        [[90, 90, 5, 5], [10, 10, 10, 10], [50, 50, 10, 10], [80, 80, 10, 10], [10, 10, 0, 10]],
        float,
    )
    r = protocols.lasher(pred, gt, None)
    # frame 1 := truth (hit); frame 2 hit; frame 3 invalid truth (-1: hit for PR); frame 4 truth
    # x=0 invalid (-1: hit); frame 5 w=0 -> previous box (80,80) -> miss
    assert r["pr"] == pytest.approx(4 / 5) and r["npr"] == pytest.approx(4 / 5)
    # SR: frames 1, 2 have IoU 1 (success for t < 1), the rest fail
    assert r["sr"] == pytest.approx(2 * 20 / 5 / 21)


def test_rgbt234_min_error_max_iou():
    gv = np.array([[0, 0, 10, 10], [0, 0, 10, 10]], float)
    gi = np.array([[30, 0, 10, 10], [0, 0, 10, 10]], float)
    pred = np.array([[30, 0, 10, 10], [25, 0, 10, 10]], float)
    r = protocols.rgbt234(pred, gv, gi)
    assert r["mpr"] == pytest.approx(
        0.5
    )  # frame 1 hits through the infrared truth, frame 2 is 25 px off
    assert protocols.rgbt234(pred, gv, gv)["mpr"] == 0.0
    r2 = protocols.rgbt234(np.array([[30, 0, 10, 10], [0, 0, 10, 10]], float), gv, gi)
    assert r2["msr"] == pytest.approx(20 / 21)


def test_vtuav_scores_the_annotated_frames_only():
    """By hand: truth on frames 1 and 11 only (VTUAV's every 10th); frame 1 hits through the IR
    truth with IoU 1 there, frame 11 is 25 px off (IoU 0); the frames between are not scored
    whatever the box."""
    n = 12
    gv, gi = np.full((n, 4), np.nan), np.full((n, 4), np.nan)
    gv[0], gi[0] = [0, 0, 10, 10], [30, 0, 10, 10]
    gv[10], gi[10] = [0, 0, 10, 10], [0, 0, 10, 10]
    pred = np.full((n, 4), 500.0)
    pred[0], pred[10] = [30, 0, 10, 10], [25, 0, 10, 10]
    r = protocols.vtuav(pred, gv, gi)
    assert r["frames"] == 2
    assert r["mpr"] == pytest.approx(0.5)
    assert r["msr"] == pytest.approx(
        (20 / 21 + 0) / 2
    )  # success at IoU > t: frame 1 for t < 1, frame 11 never
    assert "vtuav" in protocols.PROTOCOLS
