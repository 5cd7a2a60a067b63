"""CLEAR-MOT, IDF1, purity and HOTA on hand-built cases."""

import math

import numpy as np
import pytest

from pipeline.eval import evaluate
from pipeline.eval.mot import clear_mot, hota, idf1, match_frames, purity_matrix
from pipeline.io.results import TrackTable
from pipeline.io.sequence import Truth

NAN = [math.nan] * 4


def _swap_case():
    """Two targets 4 frames; tracks 10/20 follow them but swap identities at frame 3."""
    a = np.array([[0, 0, 10, 10]] * 4, float)
    b = np.array([[50, 0, 10, 10]] * 4, float)
    t10 = np.array([a[0], a[1], b[2], b[3]])
    t20 = np.array([b[0], b[1], a[2], a[3]])
    return {1: a, 2: b}, {10: t10, 20: t20}


def test_id_switch_counted_and_mota():
    gt, tr = _swap_case()
    m = clear_mot(match_frames(gt, tr, 4))
    assert m["id_switches"] == 2 and m["misses"] == 0 and m["false_positives"] == 0
    assert m["mota"] == pytest.approx(1 - 2 / 8) and m["motp"] == 1.0


def test_idf1_hand_computed():
    gt, tr = _swap_case()
    r = idf1(gt, tr)
    # best one-to-one: 1->10 (2 frames), 2->20 (2 frames): IDTP 4 of 8 and 8
    assert r["idf1"] == pytest.approx(0.5) and r["mapping"] in ({1: 10, 2: 20}, {1: 20, 2: 10})


def test_misses_and_false_positives():
    gt = {1: np.array([[0, 0, 10, 10], [0, 0, 10, 10], NAN], float)}
    tr = {5: np.array([[0, 0, 10, 10], [30, 30, 10, 10], [0, 0, 10, 10]], float)}
    m = clear_mot(match_frames(gt, tr, 3))
    assert (m["matches"], m["misses"], m["false_positives"]) == (1, 1, 2)
    assert m["mota"] == pytest.approx(1 - 3 / 2)


def test_purity_rows_sum_to_one_with_none_column():
    gt, tr = _swap_case()
    gt[1] = np.vstack([gt[1], [[0, 0, 10, 10]]])
    gt[2] = np.vstack([gt[2], [NAN]])
    tr = {k: np.vstack([v, [NAN]]) for k, v in tr.items()}
    fm = match_frames(gt, tr, 5)
    p = purity_matrix(gt, tr, fm)
    mat = np.array(p["matrix"])
    np.testing.assert_allclose(mat.sum(axis=1), 1.0)
    assert p["columns"] == ["10", "20", "none"]
    np.testing.assert_allclose(mat[0], [2 / 5, 2 / 5, 1 / 5])
    assert p["overall"] == pytest.approx((2 + 2) / 9)


def test_continuation_keeps_matches_through_ambiguity():
    # a track drifting between two close targets keeps its target while IoU >= 0.5
    gt = {1: np.array([[0, 0, 10, 10]] * 2, float), 2: np.array([[4, 0, 10, 10]] * 2, float)}
    tr = {
        7: np.array([[0, 0, 10, 10], [2, 0, 10, 10]], float),
        8: np.array([[4, 0, 10, 10], [6, 0, 10, 10]], float),
    }
    assert clear_mot(match_frames(gt, tr, 2))["id_switches"] == 0


def test_hota_perfect_and_swapped():
    gt, _ = _swap_case()
    assert hota(gt, {k: v.copy() for k, v in gt.items()}, 4)["hota"] == pytest.approx(1.0)
    gt, tr = _swap_case()
    h = hota(gt, tr, 4)
    # every TP pair has TPA 2, FNA 2, FPA 2 -> A = 2/6; detection is perfect
    assert h["deta"] == pytest.approx(1.0) and h["assa"] == pytest.approx(1 / 3)
    assert h["hota"] == pytest.approx(math.sqrt(1 / 3))


def test_evaluate_multi_keys_and_id_mapping():
    gt, tr = _swap_case()
    truth = Truth({"visible": gt, "infrared": gt}, multi=True)
    out = evaluate(truth, TrackTable(tr, {}), 4)
    for k in ("mota", "motp", "idf1", "id_switches", "purity", "hota"):
        assert k in out
    assert out["targets"]["1"]["track_id"] in (
        10,
        20,
    )  # ids differ: scored through the IDF1 assignment


def test_a_frame_without_tracks_keeps_the_previous_matches_as_trackeval_does():
    """TrackEval's CLEAR skips a frame with truth but no track box, keeping the last frame's
    matches: the continuation after it prefers the same track (no switch) although another
    overlaps the target better."""
    nan = [np.nan] * 4
    gt = {1: np.array([[0, 0, 10, 10]] * 3, float)}
    tr = {
        7: np.array([[0, 0, 10, 10], nan, [3, 0, 10, 10]], float),  # IoU 0.54 in frame 3
        8: np.array([nan, nan, [1, 0, 10, 10]], float),  # IoU 0.82 in frame 3
    }
    m = clear_mot(match_frames(gt, tr, 3))
    assert m["id_switches"] == 0 and m["misses"] == 1 and m["false_positives"] == 1


def test_sparse_truth_is_scored_on_the_annotated_frames_only():
    """With truth every 10th frame, the many-target scores equal those of the annotated frames
    alone (TrackEval given only those frames' rows): a box on another frame is no false
    positive."""
    rng = np.random.default_rng(0)
    n = 31
    start = {g: np.array([40.0 * g, 50, 20, 30]) for g in (1, 2)}
    dense = {g: np.cumsum(rng.normal(0, 2, (n, 4)), axis=0) + start[g] for g in (1, 2)}
    tracks = {t: dense[t] + rng.normal(0, 1, (n, 4)) for t in (1, 2)}
    tracks[3] = dense[1] + np.array([200.0, 0, 0, 0])  # a false track, on every frame
    sparse = {g: np.where(np.arange(n)[:, None] % 10 == 0, b, np.nan) for g, b in dense.items()}
    truth = Truth({"visible": sparse}, multi=True, sparse_every=10)
    got = evaluate(truth, TrackTable(tracks, {}), n)
    keep = np.arange(n) % 10 == 0
    only = Truth({"visible": {g: b[keep] for g, b in dense.items()}}, multi=True)
    want = evaluate(only, TrackTable({t: b[keep] for t, b in tracks.items()}, {}), int(keep.sum()))
    assert got["mot_frames"] == 4 and got["false_positives"] < 10  # not the false track's 31 rows
    for k in ("mota", "motp", "idf1", "hota", "id_switches", "false_positives", "misses"):
        assert got[k] == pytest.approx(want[k]), k
