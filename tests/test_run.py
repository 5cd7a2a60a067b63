"""``track`` end to end: run folder contents, .rrd read-back, evaluation agreement, real
footage."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.io.results import read_tracks
from pipeline.io.sequence import open_sequence
from pipeline.run import RunOptions, run_track, track
from tests.conftest import REAL_SEQUENCES
from tests.eval.test_single import _reference
from tests.rrd_helpers import blob_at, boxes_at, open_store, rows, texts


def _csv_rows(path: Path) -> list[list[str]]:
    return [r for r in csv.reader(path.read_text().splitlines())]


def test_run_folder_contract(scene, tmp_path):
    seq_dir = scene("crossing2")
    res = run_track(seq_dir, RunOptions(tracker="meanshift", out_dir=tmp_path / "run"))
    out = res.out_dir
    assert {p.name for p in out.iterdir()} >= {
        "tracks.csv",
        "targets.csv",
        "run.rrd",
        "summary.json",
        "plots",
    }
    tracks = _csv_rows(out / "tracks.csv")
    assert len(tracks) == 160 * 2  # a row per tracked target per frame
    assert all(len(r) == 10 and r[7:] == ["-1", "-1", "-1"] for r in tracks)
    targets = _csv_rows(out / "targets.csv")
    assert targets[0] == [
        "frame",
        "id",
        "status",
        "x_px",
        "y_px",
        "w_px",
        "h_px",
        "source",
        "iterations",
        "rho",
        "model_update",
        "diagnostics",
        "decision",
    ]
    assert len(targets) == 1 + 160 * 2
    s = json.loads((out / "summary.json").read_text())
    for k in (
        "tracker",
        "sequence",
        "frames",
        "targets",
        "config",
        "version",
        "seed",
        "stage_seconds",
        "fps_tracking",
        "fps_tracking_cpu",
        "fps_end_to_end",
        "complete",
        "metrics",
    ):
        assert k in s
    assert s["complete"] is True and s["frames"] == 160 and s["seed"] == 0
    assert {"mota", "idf1", "purity", "p20"} <= set(s["metrics"])
    assert {p.name for p in (out / "plots").iterdir()} == {
        "center_error.png",
        "precision.png",
        "success.png",
    }


def test_rrd_reads_back_equal_to_csv(scene, tmp_path):
    seq_dir = scene("occluder")
    res = run_track(seq_dir, RunOptions(tracker="meanshift", out_dir=tmp_path / "run"))
    out = res.out_dir
    verify = subprocess.run(
        [str(Path(sys.executable).parent / "rerun"), "rrd", "verify", str(out / "run.rrd")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert verify.returncode == 0, verify.stderr
    store = open_store(out / "run.rrd")
    tracks = {
        int(r[0]): [
            float(r[2]) - 1,
            float(r[3]) - 1,
            float(r[4]),
            float(r[5]),
        ]  # tracks.csv is 1-based
        for r in _csv_rows(out / "tracks.csv")
    }
    for frame in (1, 57, 150, 220):
        for ch in ("visible", "infrared"):
            b = boxes_at(store, f"/{ch}/targets", frame)
            np.testing.assert_allclose(
                np.hstack([b["mins"][0], b["sizes"][0]]), tracks[frame], atol=2e-3
            )
            assert b["class_ids"] == [1] and b["labels"][0].startswith("T1 ")
    # the source JPEG bytes are passed through, not re-encoded
    assert (
        blob_at(store, "/visible/image", 57) == (seq_dir / "visible" / "00057v.jpg").read_bytes()
    )
    assert (
        blob_at(store, "/infrared/image", 57) == (seq_dir / "infrared" / "00057i.jpg").read_bytes()
    )
    err = rows(store, "/metrics/1/center_error_px", ["Scalars:scalars"])
    assert err.num_rows == 220
    # the recording's series are the run's one evaluation, frame by frame
    from pipeline.eval import Assessment
    from pipeline.io.results import TrackTable

    seq = open_sequence(seq_dir)
    a = Assessment(seq.truth, TrackTable(res.boxes, {}), seq.n_frames)
    logged = np.array([v[0] for v in err["Scalars:scalars"].to_pylist()], float)
    np.testing.assert_allclose(logged, a.errors[1][err["frame"].to_numpy() - 1], rtol=1e-6)
    ev = texts(store, "/events")
    assert ev and ev[0][0] == 1 and "[start] meanshift on occluder" in ev[0][1]
    assert "/config" in [str(p) for p in store.schema().entity_paths()]


def test_evaluate_agrees_with_independent_computation(scene, tmp_path):
    seq_dir = scene("shadows")
    out = run_track(
        seq_dir, RunOptions(tracker="camshift", out_dir=tmp_path / "run", rrd=False)
    ).out_dir
    rc = main(["evaluate", str(seq_dir), str(out / "tracks.csv"), "--json"])
    assert rc == 0
    seq = open_sequence(seq_dir)
    pred = read_tracks(out / "tracks.csv", seq.n_frames).boxes.get(
        1, np.full((seq.n_frames, 4), np.nan)
    )
    gt = seq.truth.boxes["visible"][1]
    p20, auc = _reference(pred, gt)
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert abs(m["p20"] - p20) < 0.01 and abs(m["auc"] - auc) < 0.01


@pytest.mark.parametrize("tracker", ["meanshift", "camshift", "mil"])
def test_engines_run_and_report_every_frame(scene, tracker, tmp_path):
    seq_dir = scene("pole-fast")  # 32 frames
    res = run_track(
        seq_dir, RunOptions(tracker=tracker, out_dir=tmp_path / tracker, rrd=False, plots=False)
    )
    assert res.complete
    targets = _csv_rows(res.out_dir / "targets.csv")[1:]
    assert [int(r[0]) for r in targets] == list(range(1, 33))
    assert res.summary["fps_tracking"] > 0


def test_meanshift_follows_an_easy_scene(scene):
    results = track(scene("approach"), tracker="meanshift")
    gt = open_sequence(scene("approach")).truth.boxes["visible"][1]
    err = [
        np.hypot(r.targets[0].box.cx - (g[0] + g[2] / 2), r.targets[0].box.cy - (g[1] + g[3] / 2))
        for r, g in zip(results, gt, strict=True)
    ]
    assert np.mean(np.array(err) <= 20) >= 0.9


def test_csrt_kcf_clear_message_when_missing(scene, tmp_path):
    from pipeline.trackers.peers import opencv_tracker_available

    if opencv_tracker_available("csrt"):
        pytest.skip("this OpenCV has the contrib trackers")
    from pipeline.errors import InputError

    with pytest.raises(InputError, match="needs OpenCV's contrib modules"):
        run_track(scene("pole-fast"), RunOptions(tracker="csrt", out_dir=tmp_path / "x"))


# Regression floors for the classic mean-shift baseline, from measured P@20 (0.983, 0.074, 0.328)
# with margin. Intensity-histogram mean shift drifts on thermal footage; the dual tracker's IR mode
# adds contours.
REAL_FLOORS = {"otb-crossing": 0.9, "ptbtir-airplane": 0.05, "vottir-horse": 0.25}


@pytest.mark.parametrize("name", REAL_SEQUENCES)
def test_meanshift_on_real_footage(realdata, name, tmp_path):
    res = run_track(
        realdata / name, RunOptions(tracker="meanshift", out_dir=tmp_path / name, plots=False)
    )
    s = res.summary
    assert s["complete"] and s["frames"] == open_sequence(realdata / name).n_frames
    assert s["channels"] == (["visible"] if name == "otb-crossing" else ["infrared"])
    assert s["metrics"]["p20"] >= REAL_FLOORS[name]


def test_mil_on_real_footage(realdata, tmp_path):
    res = run_track(
        realdata / "otb-crossing", RunOptions(tracker="mil", out_dir=tmp_path / "mil", plots=False)
    )
    assert res.complete and len((res.out_dir / "tracks.csv").read_text().splitlines()) == 120


@pytest.mark.slow
@pytest.mark.parametrize("name", REAL_SEQUENCES)
def test_mil_on_all_real_footage(realdata, name, tmp_path):
    res = run_track(
        realdata / name, RunOptions(tracker="mil", out_dir=tmp_path / name, plots=False)
    )
    assert res.complete


def test_rrd_holds_the_truth_iou_and_failures(scene, tmp_path):
    from pipeline.io.sequence import open_sequence

    seq_dir = scene("occluded-moving")
    out = run_track(seq_dir, RunOptions(tracker="camshift", out_dir=tmp_path / "run")).out_dir
    store = open_store(out / "run.rrd")
    truth = open_sequence(seq_dir).truth
    for frame in (1, 90):
        for ch in ("visible", "infrared"):
            b = boxes_at(store, f"/{ch}/truth", frame)
            np.testing.assert_allclose(
                np.hstack([b["mins"][0], b["sizes"][0]]), truth.boxes[ch][1][frame - 1], atol=2e-3
            )
            assert b["labels"] == ["GT 1"]
            # the truth's label sits at its box's top-left corner, apart from the target's
            labels = rows(store, f"/{ch}/truth_labels", ["Points2D:positions", "Points2D:labels"])
            at = [r for r in labels.to_pylist() if r["frame"] == frame][-1]
            np.testing.assert_allclose(
                at["Points2D:positions"][0], truth.boxes[ch][1][frame - 1][:2], atol=2e-3
            )
            assert at["Points2D:labels"] == ["GT 1"]
    iou = rows(store, "/metrics/1/iou", ["Scalars:scalars"])
    assert iou.num_rows == 220
    vals = [v[0] if isinstance(v, list) else v for v in iou.column("Scalars:scalars").to_pylist()]
    assert (
        vals[0] == pytest.approx(1.0) and min(vals) == 0.0
    )  # CamShift loses the target behind the wall
    states = rows(store, "/targets/1/truth", ["StateChange:state"]).to_pylist()
    seq_states = [
        s["StateChange:state"][0]
        if isinstance(s["StateChange:state"], list)
        else s["StateChange:state"]
        for s in states
    ]
    assert seq_states[0] == "overlap" and "failure" in seq_states
    first_fail = next(
        s["frame"] for s, v in zip(states, seq_states, strict=True) if v == "failure"
    )
    assert vals[first_fail - 1] == 0.0
    ev = texts(store, "/events")
    assert any(f == first_fail and t.startswith("[failure] T1") for f, t in ev)


def test_the_centre_error_plot_draws_sparse_truth(tmp_path):
    """Truth every 10th frame: the curve goes through those frames (a line with markers), not
    isolated points between NaNs that draw nothing."""
    import cv2

    from pipeline.sinks.plots import _color, write_plots

    n = 200
    errors = np.full(n, np.nan)
    errors[::10] = np.linspace(2, 30, n // 10)
    curves = {1: {"errors": errors, "precision": np.linspace(0, 1, 51), "success": np.ones(21)}}
    write_plots(tmp_path, curves, "sparse")
    img = cv2.imread(str(tmp_path / "center_error.png"))[..., ::-1].astype(int)
    rgb = np.array(_color(0)) * 255
    drawn = (np.abs(img - rgb).sum(axis=2) < 40).sum()
    assert drawn > 300, drawn  # pixels of T1's colour: the line and its markers


def test_an_infrared_frame_read_as_three_channels_is_taken_as_grey():
    """``cv2.imread`` returns a grey PNG as three equal channels by default: the API takes it as
    the one channel it is, with the same result as the (H, W) array."""
    from pipeline import DualTracker

    vis = np.full((60, 80, 3), 90, np.uint8)
    vis[20:40, 30:40] = (40, 40, 200)
    ir = np.full((60, 80), 60, np.uint8)
    ir[20:40, 30:40] = 200
    grey = DualTracker().start((vis, ir), [(30, 20, 10, 20)])
    three = DualTracker().start((vis, np.dstack([ir] * 3)), [(30, 20, 10, 20)])
    assert three.targets[0].box == grey.targets[0].box
