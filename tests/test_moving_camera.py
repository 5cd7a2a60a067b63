"""A moving camera is said, not suffered: ``dualtrack detect`` and ``--tracker detect`` report it
in one line and in ``summary.json``, and the tracker starts no tracks on the scene's texture."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from pipeline.cli import main
from tests.stages.test_camera_motion import view, world


def _folder(root, pan_px: float, n: int = 40):
    """An IR-only folder of ``n`` 320 x 240 frames of a textured scene with a warm walker (16 x 40,
    2 px a frame in the image), the camera panning ``pan_px`` a frame; ``infrared.txt`` its
    truth."""
    rng = np.random.default_rng(11)
    w = world(rng)
    (root / "infrared").mkdir(parents=True)
    rows = []
    for k in range(n):
        img = view(w, 40 + pan_px * k, 60, rng)
        x = 60 + 2 * k
        img[120:160, x : x + 16] += 80
        cv2.imwrite(str(root / "infrared" / f"{k + 1:05d}.png"), np.clip(img, 0, 255).astype("u1"))
        rows.append(f"{x},120,16,40")
    (root / "infrared.txt").write_text("\n".join(rows) + "\n")
    return root


@pytest.mark.parametrize("pan_px,moving", [(5.0, True), (0.0, False)])
def test_detect_says_whether_the_camera_moves(tmp_path, capsys, pan_px, moving):
    seq = _folder(tmp_path / "seq", pan_px)
    assert main(["detect", str(seq), "--out", str(tmp_path / "det"), "--no-rrd"]) == 0
    s = json.loads((tmp_path / "det" / "summary.json").read_text())
    err = capsys.readouterr().err
    assert s["camera"]["moving"] is moving
    if moving:
        assert s["camera"]["moving_frames"] == 40 and s["camera"]["blocks"][0]["frames"] == [1, 40]
        assert err.count("\n") == 1 and "the camera moves on 40 of 40 frames" in err
        assert any("camera moves" in w for w in s["warnings"])
    else:
        assert err == "" and "warnings" not in s and s["recall"] == 1.0


@pytest.mark.parametrize("pan_px", [5.0, 0.0])
def test_the_detection_tracker_starts_no_tracks_on_a_moving_cameras_texture(
    tmp_path, capsys, pan_px
):
    seq = _folder(tmp_path / "seq", pan_px)
    out = tmp_path / "run"
    assert main(["track", str(seq), "--tracker", "detect", "--out", str(out), "--no-rrd"]) == 0
    s = json.loads((out / "summary.json").read_text())
    ids = {line.split(",")[1] for line in (out / "tracks.csv").read_text().splitlines() if line}
    if pan_px:
        assert s["camera"]["moving"] and ids == set()
        assert "they start no new tracks there" in capsys.readouterr().err
    else:
        assert not s["camera"]["moving"] and len(ids) == 1 and s["metrics"]["p20"] > 0.9


def test_a_panning_real_sequence_is_seen_moving_and_the_still_ones_not(realdata):
    from pipeline.io.background import SequenceBackground
    from pipeline.io.sequence import open_sequence
    from pipeline.stages.detection import DetectionConfig

    for name, moving in (
        ("vottir-horse", True),  # the camera pans and tilts with a horse
        ("ptbtir-airplane", False),
        ("otb-crossing", False),
        ("vtuav-bus1", False),  # a still camera over a road: its many detections are vehicles
    ):
        seq = open_sequence(realdata / name)
        ch = "infrared" if "infrared" in seq.channels else seq.channels[0]
        src = SequenceBackground(seq, ch, DetectionConfig())
        src.at(1)
        assert src.camera()["moving"] is moving, name
