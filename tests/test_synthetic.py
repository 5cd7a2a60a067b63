"""Synthetic scenes: deterministic by seed, truth exact against the rendered pixels, visibility."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.io.sequence import open_sequence
from pipeline.synthetic import SCENARIOS, synthesize
from pipeline.synthetic.scene import Renderer


def test_at_least_eight_scenarios_with_descriptions():
    assert len(SCENARIOS) >= 8 and all(s.description for s in SCENARIOS.values())


def test_deterministic_by_seed(tmp_path):
    a = synthesize("pole-fast", tmp_path / "a", seed=5)
    b = synthesize("pole-fast", tmp_path / "b", seed=5)
    c = synthesize("pole-fast", tmp_path / "c", seed=6)
    for f in ("visible/00010v.jpg", "infrared/00020i.jpg", "visible.txt"):
        assert (a / f).read_bytes() == (b / f).read_bytes()
    assert (a / "visible/00010v.jpg").read_bytes() != (c / "visible/00010v.jpg").read_bytes()
    assert (a / "visible.txt").read_text() == (
        c / "visible.txt"
    ).read_text()  # paths do not depend on the seed
    assert json.loads((a / "scene.json").read_text())["seed"] == 5


def test_refuses_to_overwrite(tmp_path):
    synthesize("pole-fast", tmp_path / "a")
    with pytest.raises(InputError, match="--force"):
        synthesize("pole-fast", tmp_path / "a")
    with pytest.raises(InputError, match="unknown scenario"):
        synthesize("nope", tmp_path / "b")


@pytest.mark.parametrize(
    "name, frames", [("approach", (1, 100, 200)), ("fast", (1, 23, 60)), ("shadows", (5, 150))]
)
def test_truth_matches_the_rendered_ir_silhouette(name, frames):
    """The IR blob (threshold halfway to the target's heat) has the truth box within 1.5 px per
    side."""
    sc = SCENARIOS[name]
    r = Renderer(sc, seed=0)
    actor = next(a for a in sc.actors if a.target_id == 1)
    for t in range(1, max(frames) + 1):
        _, ir, truth = r.render(t)
        if t not in frames:
            continue
        box, vis = truth[1]
        thr = sc.ir_ambient + 0.3 * actor.ir_contrast
        mask = (cv2.GaussianBlur(ir, (0, 0), 1.0) > thr).astype(np.uint8)
        _n, labels, stats, _ = cv2.connectedComponentsWithStats(mask)
        cx, cy = int(box[0] + box[2] / 2), int(box[1] + box[3] / 2)
        lab = (
            labels[cy, cx]
            or np.bincount(
                labels[
                    int(box[1]) : int(box[1] + box[3]), int(box[0]) : int(box[0] + box[2])
                ].ravel()
            ).argmax()
        )
        x, y, w, h, _ = stats[lab]
        np.testing.assert_allclose(
            [x, y, x + w, y + h], [box[0], box[1], box[0] + box[2], box[1] + box[3]], atol=1.5
        )
        assert vis == 1.0


def test_files_and_reader_round_trip(scene):
    d = scene("crossing2")
    seq = open_sequence(d)
    assert seq.layout == "rgbt234" and seq.truth.multi and (seq.width, seq.height) == (320, 240)
    assert (d / "visible" / "00001v.jpg").is_file() and (d / "infrared" / "00160i.jpg").is_file()
    meta = json.loads((d / "scene.json").read_text())
    r = Renderer(SCENARIOS["crossing2"], seed=0)
    for t in range(1, 81):
        _, _, truth = r.render(t)
    for tid in (1, 2):
        np.testing.assert_allclose(
            seq.truth.boxes["visible"][tid][79], truth[tid][0], atol=2e-3
        )  # gt.txt is 1-based
        assert seq.truth.visibility[tid][79] == pytest.approx(truth[tid][1], abs=1e-3)
    assert (
        min(meta["visibility"]["2"]) < 0.1
    )  # the far target is (nearly) fully hidden at the crossing


def test_occluders_hide_and_frames_leave(scene):
    meta = json.loads((scene("occluded-moving") / "scene.json").read_text())
    hidden = meta["hidden_frames"]["1"]
    assert len(hidden) == 1 and hidden[0][1] - hidden[0][0] >= 10


def test_target_leaving_the_frame_has_no_truth(tmp_path, monkeypatch):
    from pipeline import synthetic
    from pipeline.synthetic.scenarios import keyframes
    from pipeline.synthetic.scene import Actor, Scene

    sc = Scene(
        "exit",
        "leaves",
        160,
        120,
        12,
        (Actor("car", 40, keyframes([(1, 100, 70, 1.0), (12, 210, 70, 1.0)]), target_id=1),),
    )
    monkeypatch.setitem(synthetic.SCENARIOS, "exit", sc)
    d = synthetic.synthesize("exit", tmp_path / "exit")
    meta = json.loads((d / "scene.json").read_text())
    seq = open_sequence(d)
    gt = seq.truth.boxes["visible"][1]
    absent = meta["absent_frames"]["1"]
    assert absent and absent[-1][1] == 12
    assert np.isnan(gt[11]).all() and not np.isnan(gt[0]).any()
    assert gt[5, 0] + gt[5, 2] > 160  # partly outside: the amodal box extends past the border


def test_a_scene_of_ones_own_is_rendered_on_its_keyframed_path(tmp_path):
    """``synthesize`` takes a :class:`Scene` as well as a scenario's name: a person keyframed from
    (60, 130) to (260, 130) over 41 frames is in its truth at the path's centre (within the
    sprite's half-pixel rounding) and ``scene.json`` names the scene."""
    from pipeline.synthetic.scenarios import keyframes
    from pipeline.synthetic.scene import Actor, Scene

    path = keyframes([(1.0, 60.0, 130.0, 1.0), (41.0, 260.0, 130.0, 1.0)])
    scene = Scene("planted", "one walker", 320, 240, 41, (Actor("person", 60, path, target_id=1),))
    d = synthesize(scene, tmp_path / "s", progress=False)
    truth = np.loadtxt(d / "visible.txt", delimiter=",")
    assert truth.shape == (41, 4)
    centre = truth[:, :2] + truth[:, 2:] / 2
    want = np.array([path(t)[:2] for t in range(1, 42)])
    err = np.abs(centre - want).max()
    assert err <= 1.0, err  # 0.67 px: the sprite's rounding to whole rows and columns
    assert json.loads((d / "scene.json").read_text())["scenario"] == "planted"
