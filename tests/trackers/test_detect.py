"""The detection-driven tracker and ``dualtrack detect``: no initial boxes."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from pipeline.detect_run import run_detect
from pipeline.errors import InputError
from pipeline.run import RunOptions, run_track
from tests.rrd_helpers import boxes_at, open_store


@pytest.mark.parametrize("name", ["crossing2", "crossing3"])
def test_tracks_crossings_without_initial_boxes(scene, tmp_path, name):
    res = run_track(
        scene(name), RunOptions(tracker="detect", out_dir=tmp_path / name, rrd=False, plots=False)
    )
    m = res.summary["metrics"]
    assert res.summary["targets"] == []  # nothing given
    assert m["idf1"] >= 0.9 and m["mota"] >= 0.85, (m["idf1"], m["mota"])
    assert m["p20"] >= 0.9  # each truth scored against the track the IDF1 assignment gives it
    table = list(csv.DictReader((tmp_path / name / "targets.csv").read_text().splitlines()))
    statuses = {r["status"] for r in table}
    assert {"tentative", "tracking", "merged"} <= statuses  # births, confirmation, the crossing
    tracks = np.loadtxt(tmp_path / name / "tracks.csv", delimiter=",", ndmin=2)
    tentative = {(int(r["frame"]), int(r["id"])) for r in table if r["status"] == "tentative"}
    assert not tentative & {
        (int(f), int(i)) for f, i in tracks[:, :2]
    }  # tentative tracks are not reported


def test_image_term_is_what_keeps_identities_when_state_is_ambiguous(scene, tmp_path):
    """Fused vs state-only on the crossing with full occlusion: the image term must not hurt."""
    fused = run_track(
        scene("crossing2"),
        RunOptions(tracker="detect", out_dir=tmp_path / "f", rrd=False, plots=False),
    )
    state = run_track(
        scene("crossing2"),
        RunOptions(
            tracker="detect",
            out_dir=tmp_path / "s",
            rrd=False,
            plots=False,
            sets=["detect.association.use_image=false"],
        ),
    )
    assert fused.summary["metrics"]["idf1"] >= state.summary["metrics"]["idf1"] - 0.02


def test_detect_command_outputs_and_scores(scene, tmp_path):
    out = tmp_path / "det"
    res = run_detect(scene("crossing3"), out, progress=False)
    s = res.summary
    assert s["complete"] and s["frames"] == 200 and s["channel"] == "infrared"
    assert s["recall"] >= 0.95 and s["precision"] >= 0.9, s
    det = np.loadtxt(out / "det.txt", delimiter=",", ndmin=2)
    assert (
        det.shape[1] == 10
        and (det[:, 1] == -1).all()
        and set(np.unique(det[:, 0]).astype(int)) <= set(range(1, 201))
    )
    rois = list(csv.DictReader((out / "rois.csv").read_text().splitlines()))
    assert {"1", "0"} >= {r["accepted"] for r in rois} and any(r["accepted"] == "1" for r in rois)
    store = open_store(out / "detections.rrd")
    b = boxes_at(store, "infrared/rois", 1)
    assert b is not None and len(b["mins"]) == int((det[:, 0] == 1).sum())
    np.testing.assert_allclose(
        b["mins"], det[det[:, 0] == 1][:, 2:4] - 1, atol=0.01
    )  # det.txt is 1-based


def test_a_car_is_one_box_for_the_detect_command_and_the_tracker(tmp_path):
    """Development seed 44's lone car (18 px tall, warm body, cooler wheels): ``dualtrack detect``
    gives the regions the ``detect`` tracker uses, one box on the car in every frame where it is
    in view; the touching-body split (``split_core_fraction``, the dual tracker's whole-frame
    search) cuts its front from its rear on a third of the frames."""
    from pipeline.config import load_config
    from pipeline.eval.mot import box_ious
    from pipeline.synthetic import synthesize_random
    from pipeline.trackers.detect import DetectAndAssociate

    sc = synthesize_random(tmp_path / "car", 44, targets=1, frames=40)
    truth = np.loadtxt(sc / "visible.txt", delimiter=",", ndmin=2)

    def whole(out, sets):
        run_detect(sc, out, sets=sets, rrd=False, progress=False)
        rows = [r for r in csv.DictReader((out / "rois.csv").read_text().splitlines())]
        n = 0
        for f, t in enumerate(truth, start=1):
            boxes = [
                tuple(float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))
                for r in rows
                if int(r["frame"]) == f and r["accepted"] == "1" and r["reason"] == "ok"
            ]
            n += bool(boxes) and box_ious(np.array(boxes), t[None, :4]).max() >= 0.5
        return n

    assert whole(tmp_path / "d", []) >= 38
    assert whole(tmp_path / "split", ["detect.detection.split_core_fraction=0.7"]) <= 30
    cfg = load_config(None, []).detect
    assert (
        DetectAndAssociate(cfg).detection.split_core_fraction == cfg.detection.split_core_fraction
    )


def test_detect_initialises_the_dual_tracker(scene, tmp_path):
    res = run_track(
        scene("crossing2"),
        RunOptions(tracker="dual", detect=True, out_dir=tmp_path / "d", rrd=False, plots=False),
    )
    init = res.summary["targets"]
    assert len(init) == 2  # the two people, found in the first frames
    m = res.summary["metrics"]
    assert m["idf1"] >= 0.9 and m["p20"] >= 0.9


def _blob_frames(n_on: int, n_total: int):
    """IR frames of a warm 12 x 30 px person on noise, walking right 2 px a frame for ``n_on``
    frames, then gone."""
    from pipeline.io.sequence import FramePair

    rng = np.random.default_rng(3)
    for k in range(n_total):
        ir = (60 + rng.normal(0, 2, (120, 160))).clip(0, 255).astype(np.uint8)
        if k < n_on:
            ir[40:70, 30 + 2 * k : 42 + 2 * k] = 140
        yield FramePair(k + 1, None, ir)


@pytest.mark.parametrize(
    "coast_per_hit,max_misses,lost_at", [(0.5, 30, 8), (100.0, 30, 36), (100.0, 1, 7)]
)
def test_a_track_seen_a_few_times_coasts_a_few_frames(coast_per_hit, max_misses, lost_at):
    """Confirmed after 3 detections, seen in frames 1-5, then gone: lost once its misses exceed
    coast_per_hit x 5 (2.5: its 3rd missing frame, frame 8), not after association.max_misses (30:
    frame 36) of coasting on nothing; with the default max_misses (1), on its 2nd missing frame."""
    from pipeline.config import load_config
    from pipeline.trackers.detect import DetectAndAssociate
    from pipeline.types import TargetStatus

    cfg = load_config(
        None,
        [
            f"detect.association.coast_per_hit={coast_per_hit}",
            f"detect.association.max_misses={max_misses}",
        ],
    )
    core = DetectAndAssociate(cfg.detect)
    state, lost = None, None
    for fp in _blob_frames(5, 40):
        state, res = core.init(fp, []) if state is None else core.step(state, fp)
        if lost is None and any(r.status == TargetStatus.LOST for r in res.targets):
            lost = fp.index
    assert lost == lost_at


def test_the_sequence_background_is_read_once_per_block_and_skips_unreadable_frames(scene):
    from pipeline.io.background import SequenceBackground
    from pipeline.io.sequence import open_sequence
    from pipeline.stages.detection import DetectionConfig

    seq = open_sequence(scene("crossing2"))
    src = SequenceBackground(
        seq, "infrared", DetectionConfig(background_window_frames=80, background_samples=9)
    )
    assert src.sample_indices(0) == [
        1,
        16,
        31,
        46,
        60,
        75,
        90,
        105,
        120,
    ]  # the block and half a block after it
    assert src.sample_indices(1)[0] == 41 and src.sample_indices(1)[-1] == min(200, seq.n_frames)
    a = src.at(1)
    assert a is not None and a.static and a.frames == 9 and src.at(80) is a and src.at(81) is not a
    frames = sorted((seq.path / "infrared").iterdir())
    broken = SequenceBackground(seq, "infrared", DetectionConfig(background_samples=5))
    idx = broken.sample_indices(0)
    orig = seq.frame

    def frame(i: int, channels=None):
        if i == idx[1]:
            raise InputError(f"cannot read {frames[i - 1]}")
        return orig(i, channels)

    seq.frame = frame  # type: ignore[method-assign]
    assert broken.at(1).frames == 4


def test_the_runner_gives_the_detect_tracker_the_sequence_background(scene):
    from pipeline.config import load_config
    from pipeline.io.sequence import open_sequence
    from pipeline.trackers import make_tracker
    from pipeline.trackers.base import attach_sequence

    seq = open_sequence(scene("crossing2"))
    for sets, static in (([], True), (["detect.detection.background_init=first-frame"], False)):
        engine = make_tracker("detect", load_config(None, sets))
        attach_sequence(engine, seq)
        frames = seq.frames()
        engine.start(next(frames), [])
        engine.step(next(frames))
        assert engine.state.background.static is static
        assert engine.state.background.frames == (25 if static else 2)


def _gap_frames(gap: tuple[int, int], n_total: int, jump_px: int = 0):
    """IR frames of the warm person of :func:`_blob_frames`, walking right 2 px a frame but not to
    be seen (not detected) in frames ``gap[0]..gap[1]``; after the gap it reappears ``jump_px``
    further right."""
    from pipeline.io.sequence import FramePair

    rng = np.random.default_rng(5)
    for k in range(n_total):
        ir = (60 + rng.normal(0, 2, (120, 260))).clip(0, 255).astype(np.uint8)
        if not gap[0] <= k + 1 <= gap[1]:
            x = 20 + 2 * k + (jump_px if k + 1 > gap[1] else 0)
            ir[40:70, x : x + 12] = 140
        yield FramePair(k + 1, None, ir)


def _ids_by_frame(frames, cfg):
    from pipeline.trackers.detect import DetectAndAssociate
    from pipeline.types import TargetStatus

    core = DetectAndAssociate(cfg.detect)
    state, ids = None, {}
    for fp in frames:
        state, res = core.init(fp, []) if state is None else core.step(state, fp)
        ids[fp.index] = [r.id for r in res.targets if r.status == TargetStatus.TRACKING]
    return ids


@pytest.mark.parametrize(
    "relink_frames,resume,jump_px,back_at",
    [(60, 0.8, 0, 46), (60, 2.0, 0, 48), (0, 0.8, 0, None), (60, 0.8, 100, None)],
)
def test_a_target_lost_and_found_again_keeps_its_identity(relink_frames, resume, jump_px, back_at):
    """Seen in frames 1-20, undetected in 21-45 (lost on its 2nd missing frame), seen again from 46
    where its walk has taken it: with a lost track dormant (``relink_frames``) it has its id again
    at once (frame 46: its ROI looks as it did), or when the new track is confirmed (frame 48) with
    ``resume_min_correlation`` above 1; never when dormancy is off, nor when it reappears 100 px
    beyond where its walk took it (farther than it could have gone at 1 px a frame over its speed).
    """
    from pipeline.config import load_config

    cfg = load_config(
        None,
        [
            f"detect.association.relink_frames={relink_frames}",
            f"detect.association.resume_min_correlation={resume}",
        ],
    )
    ids = _ids_by_frame(_gap_frames((21, 45), 60, jump_px), cfg)
    assert ids[20] == [1]
    assert ids[30] == []  # lost, and not reported while dormant
    assert len(ids[55]) == 1
    assert (ids[55] == [1]) == (back_at is not None)
    if back_at is not None:
        assert ids[back_at] == [1] and ids[back_at - 1] == []


@pytest.mark.parametrize("min_perimeter_px,tracked", [(40.0, False), (0.0, True)])
def test_the_tracker_leaves_regions_under_its_own_floor_to_the_detector(min_perimeter_px, tracked):
    """A warm 5 x 12 px speck walking on noise is a region for the detector (boundary about 30 px);
    the tracker starts no track on it under ``association.min_perimeter_px`` 40, and tracks it with
    the floor off."""
    from pipeline.config import load_config
    from pipeline.io.sequence import FramePair

    def frames():
        rng = np.random.default_rng(7)
        for k in range(20):
            ir = (60 + rng.normal(0, 2, (120, 160))).clip(0, 255).astype(np.uint8)
            ir[50:62, 20 + 3 * k : 25 + 3 * k] = 140
            yield FramePair(k + 1, None, ir)

    cfg = load_config(None, [f"detect.association.min_perimeter_px={min_perimeter_px}"])
    ids = _ids_by_frame(frames(), cfg)
    assert (ids[15] != []) == tracked


@pytest.mark.parametrize("use_visible,tracked", [(False, False), (True, True)])
def test_the_tracker_uses_the_visible_channel_s_regions_only_on_request(
    tmp_path, use_visible, tracked
):
    """A person at the ground's temperature, found by the detector only in the visible channel: the
    detect tracker leaves the region alone by default (``association.use_visible_regions``) and
    tracks the person with it on."""
    import cv2

    from pipeline.config import load_config
    from pipeline.run import track
    from tests.stages.test_detection import cold_person_frames

    irs, viss = cold_person_frames(25, light_at=None)
    for ch, frames in (("infrared", irs), ("visible", viss)):
        (tmp_path / ch).mkdir()
        for k, f in enumerate(frames):
            cv2.imwrite(str(tmp_path / ch / f"{k + 1:05d}.png"), f)
        (tmp_path / f"{ch}.txt").write_text(
            "".join(f"{10 + 5 * k},50,10,24\n" for k in range(len(frames)))
        )
    cfg = load_config(None, [f"detect.association.use_visible_regions={str(use_visible).lower()}"])
    res = track(tmp_path, tracker="detect", config=cfg)
    boxes = [t.box for t in res[15].targets if t.status.value == "tracking"]
    assert (len(boxes) == 1) == tracked
    if tracked:
        assert boxes[0].cx == pytest.approx(10 + 75 + 5, abs=3) and boxes[0].cy == pytest.approx(
            62, abs=3
        )


def test_members_of_a_blob_are_placed_by_their_templates(scene, tmp_path):
    """``association.place_in_blobs``: on crossing2 the two walkers' shared blob yields both,
    each measured where its template matches (source ``blob-match``, status ``merged``) within
    a few pixels of its truth, and the identities hold through the crossing; without it both
    coast inside the blob."""
    from pipeline.config import load_config

    res = run_track(
        scene("crossing2"),
        RunOptions(tracker="detect", out_dir=tmp_path / "r", rrd=False, plots=False),
    )
    assert res.summary["metrics"]["idf1"] >= 0.99
    table = list(csv.DictReader((tmp_path / "r" / "targets.csv").read_text().splitlines()))
    placed = [r for r in table if r["source"] == "blob-match"]
    assert len(placed) >= 10 and {r["status"] for r in placed} == {"merged"}
    frames = {int(r["frame"]) for r in placed}
    both = [f for f in frames if sum(int(r["frame"]) == f for r in placed) == 2]
    assert both  # a blob around two tracked targets yields both
    gt = np.loadtxt(scene("crossing2") / "gt.txt", delimiter=",", ndmin=2)
    for r in placed:
        f = int(r["frame"])
        cx = float(r["x_px"]) + float(r["w_px"]) / 2
        truth = gt[gt[:, 0] == f]
        err = np.min(np.abs(truth[:, 2] - 1 + truth[:, 4] / 2 - cx))
        assert err <= 6.0, (f, r["id"], err)
    cfg = load_config(None, ["detect.association.place_in_blobs=false"])
    run_track(
        scene("crossing2"),
        RunOptions(tracker="detect", out_dir=tmp_path / "o", rrd=False, plots=False, config=cfg),
    )
    off = (tmp_path / "o" / "targets.csv").read_text()
    assert "blob-match" not in off and "kalman-in-blob" in off
