"""The random scene family: deterministic by seed, varied, exact truth, attributes, the dev/test
split."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.io.sequence import open_sequence
from pipeline.synthetic import DISTRACTOR_ID_BASE, json_ready, synthesize_random
from pipeline.synthetic.family import (
    ATTRIBUTES,
    DEV_SEEDS,
    DISTRACTOR_ROLES,
    TEST_SEEDS,
    draw_scene,
    parse_seed_range,
    parse_target_count,
)
from pipeline.synthetic.scene import Renderer


def test_same_seed_same_bytes_and_other_seeds_differ(tmp_path):
    a = synthesize_random(tmp_path / "a", 11, frames=40)
    b = synthesize_random(tmp_path / "b", 11, frames=40)
    c = synthesize_random(tmp_path / "c", 12, frames=40)
    files = sorted(p.relative_to(a).as_posix() for p in a.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(b).as_posix() for p in b.rglob("*") if p.is_file())
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes(), f
    assert (a / "visible/00020v.jpg").read_bytes() != (c / "visible/00020v.jpg").read_bytes()


def test_scene_json_names_the_options_that_draw_the_scene_again(tmp_path):
    # a drawn target count consumes the generator: draw_scene(seed, (2, 3)) is not
    # draw_scene(seed, 3), so tools that redraw a scene need the options it was written with
    d = synthesize_random(tmp_path / "r", 7, targets=(2, 3), size=(200, 150), frames=30)
    meta = json.loads((d / "scene.json").read_text())
    gen = meta["generator"]
    assert gen == {"targets": [2, 3], "size": [200, 150], "frames": 30}
    again = draw_scene(meta["seed"], tuple(gen["targets"]), *gen["size"], gen["frames"])
    assert json.dumps(json_ready(again.params), sort_keys=True) == json.dumps(
        meta["params"], sort_keys=True
    )
    first = Renderer(again.scene, again.render_seed).render_frame(1)
    rows = np.loadtxt(d / "gt.txt", delimiter=",", ndmin=2)
    truth = {int(r[1]): tuple(r[2:6]) for r in rows if r[0] == 1 and r[6] == 1}
    # gt.txt is 1-based (MOTChallenge), the renderer's boxes 0-based
    assert truth == {
        tid: (x + 1, y + 1, w, h) for tid, (x, y, w, h) in first.truth_visible.items() if w > 0
    }


def test_twenty_seeds_draw_twenty_different_scenes():
    drawn = [json.dumps(draw_scene(s).params, sort_keys=True, default=str) for s in range(20)]
    assert len(set(drawn)) == 20


def test_every_event_kind_occurs_within_fifty_seeds():
    seen: set[str] = set()
    for seed in range(50):
        p = draw_scene(seed).params
        for e in p["events"]:
            seen.add(
                e["event"] + (f"/{e['kind']}" if e["event"] in ("occluder", "shadow") else "")
            )
        for t in p["targets"]:
            seen |= {f"kind/{t['kind']}", f"motion/{t['motion']}", f"scale/{t['scale']}"}
            seen |= {k for k in ("entering", "crossover", "crosses_target") if t.get(k)}
            seen |= {"leaving"} if t["leaves_at"] else set()
        seen |= {"jitter"} if "camera_jitter_px" in p else set()
        seen.add(f"targets/{len(p['targets'])}")
    wanted = {
        "crossing",
        "cold-look-alike",
        "warm-distractor",
        "companion",
        "occluder/full",
        "occluder/low-wall",
        "occluder/pole",
        "shadow/building",
        "shadow/tree",
        "shadow/moving",
        "illumination-ramp",
        "flicker",
        "kind/person",
        "kind/cyclist",
        "kind/car",
        "motion/straight",
        "motion/curved",
        "motion/stopping",
        "motion/turning",
        "motion/fast",
        "scale/approach",
        "scale/recede",
        "entering",
        "leaving",
        "crossover",
        "crosses_target",
        "jitter",
        "targets/1",
        "targets/2",
        "targets/3",
    }
    assert wanted <= seen, wanted - seen


def test_drawn_ranges_hold():
    for seed in range(40):
        d = draw_scene(seed)
        sc = d.scene
        for a in sc.actors:
            if a.target_id:
                xs = np.array([a.path(t) for t in range(1, sc.n_frames + 1)])
                speed = np.hypot(*np.diff(xs[:, :2], axis=0).T)
                assert (
                    speed.max() <= 12.0 + 3.0 + 1e-6
                )  # 12 px per frame, plus at most 3 of a bend towards a crossing
                assert 0.4 - 1e-9 <= xs[:, 2].min() and xs[:, 2].max() <= 3.0 + 1e-9
        shift = d.params["sensor"]["misregistration_px"]
        assert np.hypot(*shift) <= 3.0 + 1e-3
        q = d.params["sensor"]["jpeg_quality"]
        assert 50 <= q["visible"] <= 95 and 50 <= q["infrared"] <= 95


@pytest.mark.parametrize("seed", [3, 8, 21])
def test_truth_is_the_box_of_the_drawn_silhouette(seed):
    """Each target's own (amodal) alpha as drawn in the frame: its pixel box at alpha >= 0.5 is the
    visible truth; moved by the drawn misregistration it is the infrared truth (1 px: the two are
    resampled separately)."""
    d = draw_scene(seed, n_frames=60)
    r = Renderer(d.scene, d.render_seed)
    dx, dy = d.scene.sensor.ir_shift_px
    checked = 0
    for t in range(1, 61):
        f = r.render_frame(t, masks=True)
        if t % 7:
            continue
        for tid, box in f.truth_visible.items():
            m = f.masks.get(tid)
            if box is None or m is None:
                continue
            ys, xs = np.nonzero(m >= 0.5)
            assert [xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()] == list(
                box
            )
            ib = f.truth_infrared[tid]
            if (
                ib is not None
                and 4 < box[0]
                and box[0] + box[2] < d.scene.width - 4
                and 4 < box[1]
                and box[1] + box[3] < d.scene.height - 4
            ):
                np.testing.assert_allclose(
                    ib, (box[0] + dx, box[1] + dy, box[2], box[3]), atol=1.0
                )
            checked += 1
    assert checked >= 5


def test_truth_matches_the_warm_blob_in_the_infrared_frame():
    """Independently of the renderer's masks: a warm, unoccluded person's blob in the IR frame
    (threshold at a fifth of its contrast, below its coolest part) has the infrared truth box
    within 3 px per side: the IR silhouette's edge is softened by 1 px and the optics blur up to
    1.6 px, which a threshold this low reaches past the edge."""
    import cv2

    checked = 0
    for seed in range(200):
        if checked >= 4:
            break
        d = draw_scene(seed, targets=1, n_frames=30)
        a = d.scene.actors[0]
        if a.kind != "person" or a.ir_contrast < 50 or len(d.scene.actors) > 1:
            continue
        r = Renderer(d.scene, d.render_seed)
        f = r.render_frame(1)
        box = f.truth_infrared[1]
        if box is None or f.in_frame[1] < 1.0 or box[3] < 20:
            continue
        x, y, w, h = (int(v) for v in box)
        pad = 6
        roi = cv2.GaussianBlur(f.infrared_float, (0, 0), 1.0)[
            max(y - pad, 0) : y + h + pad, max(x - pad, 0) : x + w + pad
        ]
        ring = np.concatenate(
            [roi[:2].ravel(), roi[-2:].ravel(), roi[:, :2].ravel(), roi[:, -2:].ravel()]
        )
        mask = (roi > np.median(ring) + 0.2 * a.ir_contrast).astype(
            np.uint8
        )  # shoes (heat 0.4) included
        n, _labels, stats, _ = cv2.connectedComponentsWithStats(mask)
        if n < 2:
            continue
        k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        bx, by, bw, bh = stats[k, :4]
        bx, by = bx + max(x - pad, 0), by + max(y - pad, 0)
        np.testing.assert_allclose(
            [bx, by, bx + bw, by + bh],
            [box[0], box[1], box[0] + box[2], box[1] + box[3]],
            atol=3.0,
        )
        checked += 1
    assert checked >= 4


def test_written_truth_is_the_rendered_truth(tmp_path):
    d = synthesize_random(tmp_path / "r", 21, frames=30)
    drawn = draw_scene(21, n_frames=30)
    r = Renderer(drawn.scene, drawn.render_seed)
    seq = open_sequence(d)
    for t in range(1, 31):
        f = r.render_frame(t)
        for tid in f.truth_visible:
            for ch, tb in (("visible", f.truth_visible), ("infrared", f.truth_infrared)):
                want = tb[tid]
                got = (
                    seq.truth.boxes["visible"][tid][t - 1]
                    if seq.truth.multi
                    else seq.truth.boxes[ch][tid][t - 1]
                )
                if seq.truth.multi and ch == "infrared":
                    continue  # a MOT gt.txt holds the visible truth for both channels
                if want is None:
                    assert np.isnan(got).all()
                else:
                    np.testing.assert_allclose(got, want, atol=1e-3)


def test_files_attributes_and_reader(tmp_path):
    d = synthesize_random(tmp_path / "r", 8, frames=60)
    seq = open_sequence(d)
    meta = json.loads((d / "scene.json").read_text())
    assert (
        seq.layout == "rgbt234"
        and seq.n_frames == 60
        and meta["seed"] == 8
        and meta["family"] == "random"
    )
    assert set(meta["frame_attributes"]["1"]) == set(ATTRIBUTES)
    # the scene's attributes in the named scenes' codes (RGBT234's, LasHeR's OV)
    from pipeline.io.attributes import LASHER_ATTRIBUTES, RGBT234_ATTRIBUTES
    from pipeline.synthetic import ATTRIBUTES as NAMED

    codes = set(RGBT234_ATTRIBUTES) | set(LASHER_ATTRIBUTES)
    assert meta["attributes"] and set(meta["attributes"]) <= codes
    assert {c for cs in NAMED.values() for c in cs} <= codes
    assert meta["params"]["targets"] and meta["params"]["sensor"]["jpeg_quality"]["visible"] >= 50


def test_ir16_writes_16_bit_frames_that_read_back_normalized(tmp_path):
    d = synthesize_random(tmp_path / "r", 2, frames=30, ir16=True)
    seq = open_sequence(d)
    f = seq.frame(1)
    assert f.infrared_raw.dtype == np.uint16 and f.infrared.dtype == np.uint8


def test_split_and_option_parsing():
    assert set(DEV_SEEDS).isdisjoint(TEST_SEEDS) and len(TEST_SEEDS) >= 80
    assert parse_seed_range("3-5") == range(3, 6) and parse_seed_range("7") == range(7, 8)
    assert parse_target_count("2-3") == (2, 3) and parse_target_count(None) is None
    for bad in ("5-3", "-1", "a"):
        with pytest.raises(ValueError):
            parse_seed_range(bad)
    for bad in ("0", "2-9", "x"):
        with pytest.raises(ValueError):
            parse_target_count(bad)
    with pytest.raises(InputError, match="non-negative"):
        synthesize_random("/nonexistent/never-written", -1)


def test_target_count_is_honoured():
    assert {len(draw_scene(s, targets=3).params["targets"]) for s in range(5)} == {3}
    assert {len(draw_scene(s, targets=(2, 3)).params["targets"]) for s in range(20)} == {2, 3}


def test_moving_objects_that_are_not_targets_are_distractor_rows_of_the_truth(tmp_path):
    d = synthesize_random(
        tmp_path / "r", 1, targets=(2, 3), frames=60
    )  # seed 1 draws a crossing object
    drawn = draw_scene(1, (2, 3), n_frames=60)
    movers = [i for i, role in drawn.roles.items() if role in DISTRACTOR_ROLES]
    assert movers
    rows = [line.split(",") for line in (d / "gt.txt").read_text().splitlines()]
    assert {(r[6], r[7]) for r in rows if int(r[1]) >= DISTRACTOR_ID_BASE} == {("0", "8")}
    seq = open_sequence(d)
    assert set(seq.truth.distractors) == {DISTRACTOR_ID_BASE + i for i in movers}
    assert set(seq.truth.primary()) == {a.target_id for a in drawn.scene.actors if a.target_id > 0}
    r = Renderer(drawn.scene, drawn.render_seed)
    seen = 0
    for t in range(1, 61):
        f = r.render_frame(t)
        for i in movers:
            got = seq.truth.distractors[DISTRACTOR_ID_BASE + i][t - 1]
            if f.others[i] is None:
                assert np.isnan(got).all()
            else:
                np.testing.assert_allclose(got, f.others[i], atol=1e-3)
                seen += 1
    assert seen > 0
