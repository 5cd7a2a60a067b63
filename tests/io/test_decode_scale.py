"""Frames read smaller (``--decode-scale``): libjpeg's DCT scaling, other formats resized, the
automatic choice, and a run whose boxes come out in the source's px."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.io.frames import _decode_jpeg
from pipeline.io.sequence import open_sequence
from pipeline.run import RunOptions, auto_decode_scale, run_track
from pipeline.types import BBox, InitTarget
from tests.conftest import write_frames
from tests.rrd_helpers import boxes_at, open_store


def _textured(h: int, w: int) -> np.ndarray:
    rng = np.random.default_rng(2)
    img = cv2.GaussianBlur(rng.integers(0, 255, (h, w, 3)).astype(np.float32), (0, 0), 3.0)
    return cv2.normalize(img, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)


@pytest.mark.parametrize("scale", [2, 4, 8])
def test_a_jpeg_read_smaller_is_its_area_average_at_the_rounded_up_size(scale):
    """libjpeg's DCT scaling: ``ceil(size / scale)`` px; its luminance within 0.5 grey levels
    (mean; 0.16-0.23 measured) of the full decode averaged over the same blocks, its colours
    within 2.5 (0.9-1.8: the chroma is subsampled in the file), where taking every
    ``scale``-th pixel is 4-23 off."""
    img = _textured(97, 130)
    data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
    small = _decode_jpeg(data, False, scale)
    h, w = -(-97 // scale), -(-130 // scale)
    assert small.shape == (h, w, 3)
    full = _decode_jpeg(data, False, 1)
    pad = cv2.copyMakeBorder(full, 0, h * scale - 97, 0, w * scale - 130, cv2.BORDER_REPLICATE)
    ref = cv2.resize(pad, (w, h), interpolation=cv2.INTER_AREA)
    assert np.abs(small.astype(int) - ref).mean() < 2.5
    grey = _decode_jpeg(data, True, scale)
    assert grey.shape == (h, w)
    assert np.abs(grey.astype(int) - cv2.cvtColor(ref, cv2.COLOR_BGR2GRAY)).mean() < 0.5
    picked = full[::scale, ::scale]
    assert np.abs(picked.astype(int) - ref).mean() > 2 * np.abs(small.astype(int) - ref).mean()


@pytest.mark.parametrize("ext", [".jpg", ".png"])
def test_a_sequence_read_at_half_size_gives_half_frames_and_keeps_the_source_bytes(tmp_path, ext):
    write_frames(tmp_path / "visible", 3, size=(65, 49), ext=ext)
    write_frames(tmp_path / "infrared", 3, size=(65, 49), color=False, ext=ext)
    seq = open_sequence(tmp_path)
    full = seq.frame(2)
    seq.decode_at(2)
    fp = seq.frame(2)
    assert fp.scale == 2 and fp.shape == (25, 33) and fp.infrared.shape == (25, 33)
    assert (seq.width, seq.height) == (65, 49) and seq.scaled_size == (33, 25)
    if ext == ".jpg":  # decoded at that size
        assert np.array_equal(fp.visible, _decode_jpeg(full.visible_encoded.data, False, 2))
    else:  # read whole, then area-averaged
        ref = cv2.resize(full.visible, (33, 25), interpolation=cv2.INTER_AREA)
        assert np.array_equal(fp.visible, ref)
    assert fp.visible_encoded.data == full.visible_encoded.data  # the source file, whole
    with pytest.raises(ValueError):
        seq.decode_at(3)


@pytest.mark.parametrize(
    ("size", "ext", "box", "expected"),
    [
        ((1920, 1080), ".jpg", (500, 90, 67, 80), 2),  # vtuav-bus1's bus
        ((1920, 1080), ".jpg", (500, 90, 40, 80), 1),  # 20 px at half: too small
        ((1920, 1080), ".jpg", (500, 90, 300, 300), 2),  # 270 px frame side at 1/4
        ((1920, 1080), ".png", (500, 90, 67, 80), 1),  # no DCT scaling to gain from
        ((320, 240), ".jpg", (100, 90, 67, 80), 1),  # 120 px frame side at half
    ],
)
def test_auto_reads_smaller_only_large_jpeg_frames_with_large_targets(
    tmp_path, size, ext, box, expected
):
    write_frames(tmp_path / "visible", 2, size=size, ext=ext)
    seq = open_sequence(tmp_path, channel="visible")
    assert auto_decode_scale(seq, [InitTarget(1, BBox(*box))]) == expected
    assert auto_decode_scale(seq, []) == 1


def _boxes(path):
    with open(path) as f:
        return {
            (int(r["frame"]), int(r["id"])): BBox(
                *(float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))
            )
            for r in csv.DictReader(f)
        }


def test_a_run_on_half_size_frames_writes_boxes_in_the_sources_px(scene, tmp_path):
    """crossing3 (640 x 480, three people) tracked at half size: the boxes of targets.csv and of
    the recording are in the source's px and follow the people as the whole-size run does."""
    seq_dir = scene("crossing3")
    runs = {}
    for s in (1, 2):
        res = run_track(
            seq_dir,
            RunOptions(out_dir=tmp_path / f"s{s}", plots=False, progress=False, decode_scale=s),
        )
        assert res.complete and res.summary["decode_scale"] == s
        runs[s] = res
    half, whole = runs[2].summary["metrics"], runs[1].summary["metrics"]
    assert half["p20"] >= 0.95 and half["auc"] >= whole["auc"] - 0.1, (half, whole)
    a, b = _boxes(tmp_path / "s1" / "targets.csv"), _boxes(tmp_path / "s2" / "targets.csv")
    ious = [a[k].iou(b[k]) for k in a.keys() & b.keys()]
    assert np.median(ious) > 0.8  # 0.93 measured
    store = open_store(tmp_path / "s2" / "run.rrd")
    for frame in (1, 60, 120):
        got = boxes_at(store, "/visible/targets", frame)
        for i, label in enumerate(got["labels"]):
            want = b[(frame, int(label.split()[0][1:]))]  # "T2 tracking"
            np.testing.assert_allclose(
                np.hstack([got["mins"][i], got["sizes"][i]]), want.as_tuple(), atol=0.01
            )


def test_decode_scale_is_refused_where_the_targets_are_detected(scene, tmp_path):
    with pytest.raises(InputError, match="--decode-scale"):
        run_track(
            scene("crossing2"),
            RunOptions(tracker="detect", out_dir=tmp_path / "d", decode_scale=2, progress=False),
        )


def test_track_in_memory_on_a_sequence_read_smaller_answers_in_the_sources_px(scene):
    """:func:`pipeline.run.track` on a :class:`Sequence` read at half size starts from the
    initial boxes in the source's px and answers in them."""
    from pipeline.io.init import resolve_init
    from pipeline.run import track

    seq = open_sequence(scene("dusk"))
    first = resolve_init(seq, None)[0].box
    whole = track(seq)
    seq.decode_at(2)
    half = track(seq)
    assert half[0].targets[0].box.iou(first) > 0.95
    ious = [a.targets[0].box.iou(b.targets[0].box) for a, b in zip(whole, half, strict=True)]
    assert np.median(ious) > 0.8
