"""Purity and IDF1 on the frames where each target is visible enough (``*_visible``)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.eval import evaluate
from pipeline.io.results import TrackTable
from pipeline.io.sequence import Truth
from tests.eval.boxes import held

N = 10


def _const(box, frames=None):
    return held(box, N, frames)


def _truth(vis1):
    gt = {1: _const([0, 0, 10, 10]), 2: _const([40, 0, 10, 10])}
    return Truth({"visible": gt}, {1: np.asarray(vis1, float), 2: np.ones(N)}, {}, True)


def test_a_hidden_stretch_leaves_the_scores_and_its_track_boxes_out():
    # target 1 is hidden on frames 4-7 (visibility 0.1): its track (id 1) coasts away on 4-5
    # (a miss, no overlap) and sits on it on 6-7 (IoU 1, but the box is an ignore region)
    vis = [1, 1, 1, 1, 0.1, 0.1, 0.1, 0.1, 1, 1]
    t1 = _const([0, 0, 10, 10])
    t1[4:6] = [100, 100, 10, 10]
    tracks = TrackTable({1: t1, 2: _const([40, 0, 10, 10])}, {})
    m = evaluate(_truth(vis), tracks, N)
    # all frames: target 1 matched on 8 of 10 frames; IDF1 = 2 IDTP / (gt + pred boxes)
    assert m["purity"]["overall"] == pytest.approx(18 / 20)
    assert m["idf1"] == pytest.approx(2 * 18 / (20 + 20))
    # visible frames: 6 + 10 truth boxes; track 1's boxes on 6-7 dropped, on 4-5 two FPs
    assert m["visible_target_frames"] == 16
    assert m["purity_visible"] == pytest.approx(1.0)
    assert m["idf1_visible"] == pytest.approx(2 * 16 / (16 + 18))


def test_a_swap_while_hidden_is_still_counted_on_the_visible_frames():
    vis = [1, 1, 1, 0.0, 0.0, 1, 1, 1, 1, 1]
    # the tracks swap targets during the hidden frames: identities wrong on 5-9
    a, b = _const([0, 0, 10, 10]), _const([40, 0, 10, 10])
    a[5:], b[5:] = b[5:], a[5:].copy()
    m = evaluate(_truth(vis), TrackTable({1: a, 2: b}, {}), N)
    # target 1: 3 of its 8 visible frames on track 1, 5 on track 2
    assert m["visible_target_frames"] == 18
    assert m["purity_visible"] == pytest.approx((5 + 5) / 18)


def test_fully_visible_truth_gives_the_all_frames_figures():
    tracks = TrackTable({1: _const([1, 0, 10, 10]), 2: _const([40, 0, 10, 10])}, {})
    m = evaluate(_truth(np.ones(N)), tracks, N)
    assert m["idf1_visible"] == m["idf1"] and m["purity_visible"] == m["purity"]["overall"]
    assert m["visible_target_frames"] == 2 * N


def test_no_visibility_column_gives_no_visible_scores():
    gt = {1: _const([0, 0, 10, 10]), 2: _const([40, 0, 10, 10])}
    tracks = TrackTable({1: gt[1], 2: gt[2]}, {})
    m = evaluate(Truth({"visible": gt}, {}, {}, True), tracks, N)
    assert "idf1_visible" not in m and "purity_visible" not in m
