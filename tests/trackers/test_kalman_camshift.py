"""Kalman-CAMShift on the paper's experiments: kept where plain CamShift loses the target."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from pipeline.eval.single import center_errors
from pipeline.io.sequence import open_sequence
from pipeline.run import RunOptions, run_track, track
from tests.rrd_helpers import boxes_at, open_store

SCENES = ("occluded-static", "occluded-moving", "pole-fast")


def _p20(seq_dir, results):
    gt = open_sequence(seq_dir).truth.primary()[1]
    boxes = np.array(
        [
            r.targets[0].box.as_tuple() if r.targets[0].status.is_reported else [np.nan] * 4
            for r in results
        ]
    )
    err = center_errors(boxes, gt)
    return float(np.mean(err[~np.isnan(err)] <= 20))


@pytest.mark.parametrize("name", SCENES)
def test_kept_where_camshift_loses_it(scene, name):
    d = scene(name)
    kc = track(d, tracker="kalman-camshift")
    cs = track(d, tracker="camshift")
    assert _p20(d, kc) >= 0.9
    assert _p20(d, cs) < 0.7
    meta = json.loads((d / "scene.json").read_text())
    hidden = meta["hidden_frames"]["1"]
    if hidden:  # re-acquired within 5 frames of re-appearing (visibility back to >= 0.5)
        vis = meta["visibility"]["1"]
        reappear = next(i + 1 for i in range(hidden[0][1], len(vis)) if vis[i] >= 0.5)
        back = next(r.frame for r in kc[hidden[0][0] :] if r.targets[0].status.value == "tracking")
        assert back - reappear <= 5
        statuses = {r.targets[0].status.value for r in kc}
        assert "occluded-partial" in statuses or "occluded-severe" in statuses


def test_diagnostics_in_targets_csv_and_rrd(scene, tmp_path):
    out = run_track(
        scene("occluded-moving"), RunOptions(tracker="kalman-camshift", out_dir=tmp_path / "r")
    ).out_dir
    rows = list(csv.DictReader((out / "targets.csv").read_text().splitlines()))
    diag = dict(kv.split("=") for kv in rows[100]["diagnostics"].split(";"))
    assert {"d", "area_px2", "min_area_px2", "severe_run"} <= set(diag)
    assert {r["status"] for r in rows} >= {"tracking", "occluded-partial"}
    store = open_store(out / "run.rrd")
    for entity in ("/visible/prediction", "/visible/search", "/infrared/search"):
        assert boxes_at(store, entity, 100) is not None, entity
    paths = {str(p) for p in store.schema().entity_paths()}
    assert "/diagnostics/1/d" in paths and "/diagnostics/1/area_px2" in paths


def test_lost_then_reacquired_when_k0_is_small(scene):
    from pipeline.config import load_config

    cfg = load_config(
        None,
        [
            "kalman_camshift.occlusion.max_severe_frames=3",
            "kalman_camshift.occlusion.distance_threshold=0.4",
        ],
    )
    res = track(scene("occluded-moving"), tracker="kalman-camshift", config=cfg)
    kinds = [e.kind.value for r in res for e in r.events]
    statuses = [r.targets[0].status.value for r in res]
    if "occluded-severe" in statuses:
        assert "lost" in kinds and "re-acquired" in kinds
        assert statuses[-1] == "tracking"


def _frames_of_a_red_square_that_vanishes(n_seen: int, n: int, speed: float):
    """BGR frames: a red square moving right at ``speed`` px/frame on grey, gone after frame
    ``n_seen``."""
    from pipeline.io.sequence import FramePair

    out = []
    for k in range(n):
        img = np.full((120, 160, 3), 128, np.uint8)
        if k < n_seen:
            x = int(40 + speed * k)
            img[50:70, x : x + 20] = (30, 30, 220)
        out.append(FramePair(k + 1, img, None))
    return out


def test_a_coasting_prediction_that_leaves_the_frame_ends_the_track():
    from pipeline.config import load_config
    from pipeline.trackers import kalman_camshift as kc
    from pipeline.types import BBox, InitTarget, TargetStatus

    cfg = load_config(None, [])
    frames = _frames_of_a_red_square_that_vanishes(20, 80, 3.0)
    core = kc.KalmanCamShift(cfg.kalman_camshift)
    state, _ = core.init(frames[0], [InitTarget(1, BBox(40, 50, 20, 20))])
    statuses, events = [], []
    for fp in frames[1:]:
        state, res = core.step(state, fp)
        statuses.append(res.targets[0].status)
        events += [e.text for e in res.events]
    assert statuses[10] == TargetStatus.TRACKING
    assert (
        TargetStatus.LOST in statuses
    )  # the prediction went on to the right edge: lost, not occluded for ever
    first_lost = statuses.index(TargetStatus.LOST)
    assert all(s == TargetStatus.LOST for s in statuses[first_lost:])
    assert any("left the frame" in e for e in events)
    assert state.targets[0].kf.box.cx <= 160 + 20  # and its motion stopped at the edge


def test_coasting_is_bounded_in_time():
    from dataclasses import replace

    from pipeline.config import load_config
    from pipeline.trackers import kalman_camshift as kc
    from pipeline.types import BBox, InitTarget, TargetStatus

    cfg = load_config(None, [])
    kcc = cfg.kalman_camshift
    occlusion = replace(kcc.occlusion, max_missing_frames=10, max_severe_frames=1000)
    cfg = replace(cfg, kalman_camshift=replace(kcc, occlusion=occlusion))
    frames = _frames_of_a_red_square_that_vanishes(10, 40, 0.0)  # it stays where it was, hidden
    core = kc.KalmanCamShift(cfg.kalman_camshift)
    state, _ = core.init(frames[0], [InitTarget(1, BBox(40, 50, 20, 20))])
    statuses = []
    for fp in frames[1:]:
        state, res = core.step(state, fp)
        statuses.append(res.targets[0].status)
    assert statuses[8] == TargetStatus.TRACKING and statuses[-1] == TargetStatus.LOST
    assert statuses.index(TargetStatus.LOST) == 9 + 10  # the 11th frame without a measurement


def test_background_weights_down_weight_the_colours_of_the_surround():
    """Exact CBWH weights on a tiny feature image: the target's own bin keeps 1, the bin it shares
    with the surround gets o* / o_u, and the surround's commonest colour the least."""
    from pipeline.stages.camshift import Feature, background_weights, box_mask, weighted_model
    from pipeline.types import BBox

    bins = np.zeros((40, 40), np.uint8)  # bin 0: the ground
    bins[10:30, 10:19] = (
        2  # bin 2: a patch of the ground's second colour, the surround's left part
    )
    box = BBox(16, 16, 8, 8)
    body = box_mask(bins.shape, box)
    bins[body] = 1  # bin 1: the target's own colour, inside its ellipse
    bins[22:24][body[22:24]] = 2  # the target's lower part shares bin 2 with the surround
    f = Feature(bins, np.ones(bins.shape, bool), 4)
    w = background_weights(
        f, box, 2.0
    )  # surround: [12, 28) x [12, 28) outside the ellipse of 9.6 x 9.6
    big = np.zeros(bins.shape, bool)
    big[12:28, 12:28] = True
    ring = big & ~box_mask(bins.shape, BBox(15.2, 15.2, 9.6, 9.6))
    counts = np.bincount(bins[ring], minlength=4).astype(
        float
    )  # ground (bin 0) and patch (bin 2) only
    assert counts[1] == 0 and counts[0] > 0 and counts[2] > 0
    rare = min(counts[0], counts[2])
    np.testing.assert_allclose(w, [rare / counts[0], 1.0, rare / counts[2], 1.0], rtol=1e-12)
    q = np.array([0.25, 0.5, 0.25, 0.0])
    m = weighted_model(q, w)
    assert m.sum() == pytest.approx(1.0) and m[1] > 0.5  # the target's own colour counts more
    assert (
        background_weights(f, BBox(0, 0, 40, 40), 1.0).tolist() == [1.0] * 4
    )  # no surround: unweighted
