"""Every layout of docs/formats.md, channel detection, 16-bit IR, and the bad-input errors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.io.init import resolve_init
from pipeline.io.sequence import open_sequence
from pipeline.types import BBox
from tests.conftest import write_boxes, write_frames

N = 5
TRUTH0 = [10, 10, 10, 10]  # the moving square of write_frames, frame 1, 0-based


def _rgbt234(root):
    write_frames(root / "visible", N, name="{:05d}v")
    write_frames(root / "infrared", N, color=False, name="{:05d}i")
    write_boxes(root / "visible.txt", N)
    write_boxes(root / "infrared.txt", N)
    return root


def _gtot(root):
    write_frames(root / "v", N, name="{:05d}_v", ext=".png")
    write_frames(root / "i", N, color=False, name="{:05d}_i", ext=".png")
    write_boxes(root / "groundTruth_v.txt", N, sep=" ", corners=True)
    write_boxes(root / "groundTruth_i.txt", N, sep=" ", corners=True)
    return root


def _vot_rgbt(root):
    write_frames(root / "color", N)
    write_frames(root / "ir", N, color=False)
    lines = [
        f"{10 + i},10,{20 + i},10,{20 + i},20,{10 + i},20" for i in range(N)
    ]  # 8-value polygons
    (root / "groundtruth.txt").write_text("\n".join(lines) + "\n")
    return root


def _vtuav(root):
    write_frames(root / "rgb", 25)
    write_frames(root / "ir", 25, color=False)
    rows = [f"{10 + i} 10 10 10" for i in (0, 10, 20)]  # x y w h, every 10th frame (VTUAV)
    (root / "rgb.txt").write_text("\n".join(rows) + "\n")
    (root / "ir.txt").write_text("\n".join(rows) + "\n")
    return root


def _otb(root):
    write_frames(root / "img", N, name="{:04d}")
    write_boxes(root / "groundtruth_rect.txt", N, sep="\t", base=1.0)
    return root


def _vot(root):
    write_frames(root, N, color=False, name="{:08d}", ext=".png")
    write_boxes(root / "groundtruth.txt", N)
    return root


def _mot(root):
    write_frames(root / "img1", N, name="{:06d}")
    (root / "gt").mkdir()
    rows = [f"{i + 1},7,{11 + i},11,10,10,1,1,1" for i in range(N)]  # 1-based
    (root / "gt" / "gt.txt").write_text("\n".join(rows) + "\n")
    return root


def _video(root):
    root.mkdir(parents=True, exist_ok=True)
    for name, color in (("visible", True), ("infrared", False)):
        vw = cv2.VideoWriter(
            str(root / f"{name}.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48), True
        )
        rng = np.random.default_rng(0)
        for i in range(N):
            img = rng.integers(40, 80, (48, 64, 3), dtype=np.uint8)
            img[10:20, 10 + i : 20 + i] = (30, 60, 220) if color else 220
            vw.write(img)
        vw.release()
    write_boxes(root / "visible.txt", N)
    return root


LAYOUTS = {
    "rgbt234": (_rgbt234, ("visible", "infrared")),
    "gtot": (_gtot, ("visible", "infrared")),
    "vot-rgbt": (_vot_rgbt, ("visible", "infrared")),
    "vtuav": (_vtuav, ("visible", "infrared")),
    "otb": (_otb, ("visible",)),
    "vot": (_vot, ("infrared",)),
    "mot": (_mot, ("visible",)),
    "video-pair": (_video, ("visible", "infrared")),
}


@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_layouts_read_with_truth_in_our_convention(tmp_path, layout):
    build, channels = LAYOUTS[layout]
    seq = open_sequence(build(tmp_path / "seq"))
    assert seq.layout == layout
    assert seq.channels == channels
    pairs = list(seq.frames())
    assert len(pairs) == seq.n_frames and pairs[0].index == 1 and pairs[-1].index == seq.n_frames
    assert pairs[0].shape == (48, 64)
    if "visible" in channels:
        assert pairs[0].visible.shape == (48, 64, 3) and pairs[0].visible.dtype == np.uint8
    if "infrared" in channels:
        assert pairs[0].infrared.shape == (48, 64)
    truth = seq.truth.primary()
    tid = next(iter(truth))
    np.testing.assert_allclose(truth[tid][0], TRUTH0)
    if layout == "vtuav":
        np.testing.assert_allclose(truth[tid][10], [20, 10, 10, 10])
        assert np.isnan(truth[tid][1]).all()
    else:
        np.testing.assert_allclose(truth[tid][N - 1], [10 + N - 1, 10, 10, 10])
    targets = resolve_init(seq)
    assert targets[0].box == BBox(*TRUTH0) and targets[0].id == tid


def test_source_bytes_are_kept_for_passthrough(tmp_path):
    seq = open_sequence(_rgbt234(tmp_path / "s"))
    f = seq.frame(3)
    assert f.visible_encoded.media_type == "image/jpeg"
    assert f.visible_encoded.data == (tmp_path / "s" / "visible" / "00003v.jpg").read_bytes()
    assert f.infrared_encoded.data == (tmp_path / "s" / "infrared" / "00003i.jpg").read_bytes()


def test_a_frame_of_one_channel_reads_only_that_channel(tmp_path, monkeypatch):
    """``frame(i, channels)`` decodes only the channels asked for (the background estimate reads
    25 frames of one channel), and gives them as the whole pair does."""
    seq = open_sequence(_rgbt234(tmp_path / "s"))
    reads = []
    src = seq.sources["visible"]
    orig = src.read
    monkeypatch.setattr(src, "read", lambda i: reads.append(i) or orig(i))
    f = seq.frame(3, {"infrared"})
    assert f.visible is None and reads == []
    np.testing.assert_array_equal(f.infrared, seq.frame(3).infrared)
    assert reads == [2]
    assert seq.frame(3, ("infrared", "visible")).visible is not None


def test_frames_stream_lazily(tmp_path, monkeypatch):
    seq = open_sequence(_rgbt234(tmp_path / "s"))
    reads = []
    src = seq.sources["visible"]
    orig = src.read
    monkeypatch.setattr(src, "read", lambda i: reads.append(i) or orig(i))
    it = seq.frames()
    assert reads == []  # nothing decoded until asked
    next(it)
    next(it)
    assert reads == [0, 1]


def test_channel_detection_and_override(tmp_path):
    grey = _vot(tmp_path / "g")
    assert open_sequence(grey).channels == ("infrared",)
    assert open_sequence(grey, channel="visible").channels == ("visible",)
    colour = _otb(tmp_path / "c")
    assert open_sequence(colour).channels == ("visible",)
    both = _rgbt234(tmp_path / "b")
    assert open_sequence(both, channel="infrared").channels == ("infrared",)


def test_16bit_ir_is_normalized_and_raw_kept(tmp_path):
    root = tmp_path / "s"
    write_frames(root / "visible", N, ext=".png")
    write_frames(root / "infrared", N, ext=".png", dtype=np.uint16)
    seq = open_sequence(root)
    f = seq.frame(1)
    assert f.infrared_raw.dtype == np.uint16 and f.infrared.dtype == np.uint8
    assert seq.ir_norm.kind == "percentile"
    assert (
        f.infrared[12, 12] == 255 and f.infrared[40, 50] < 60
    )  # hot square saturates, background stays dark
    assert (
        f.infrared_encoded is None
    )  # 16-bit PNG is not passed through; the sink encodes the 8-bit frame


def test_gt_txt_takes_precedence(tmp_path):
    root = _rgbt234(tmp_path / "s")
    (root / "gt.txt").write_text("1,3,1,1,5,5,1,1,1\n1,4,31,1,5,5,1,1,1\n")
    seq = open_sequence(root)
    assert seq.truth.multi and list(seq.truth.primary()) == [3, 4]
    assert [t.id for t in resolve_init(seq)] == [3, 4]


# ---------------------------------------------------------------- bad input
def test_missing_folder(tmp_path):
    with pytest.raises(InputError, match="sequence folder not found"):
        open_sequence(tmp_path / "nope")


def test_unrecognised_layout_names_the_layouts(tmp_path):
    (tmp_path / "s" / "frames_here").mkdir(parents=True)
    with pytest.raises(
        InputError, match=r"unrecognised sequence layout .*looked for: rgbt234.*gtot.*otb"
    ):
        open_sequence(tmp_path / "s")


def test_empty_sequence(tmp_path):
    (tmp_path / "s" / "visible").mkdir(parents=True)
    (tmp_path / "s" / "infrared").mkdir(parents=True)
    with pytest.raises(InputError, match="empty sequence: no visible frames"):
        open_sequence(tmp_path / "s")


def test_frame_count_mismatch_names_both(tmp_path):
    root = tmp_path / "s"
    write_frames(root / "visible", 5)
    write_frames(root / "infrared", 4, color=False)
    with pytest.raises(
        InputError,
        match=(
            r"different frame counts: 5 visible frames in .*visible vs 4 infrared frames in "
            r".*infrared"
        ),
    ):
        open_sequence(root)


def test_frame_size_mismatch_and_align_resize(tmp_path):
    root = tmp_path / "s"
    write_frames(root / "visible", 3, size=(64, 48))
    write_frames(root / "infrared", 3, size=(32, 24), color=False)
    (root / "infrared.txt").write_text("5,5,5,5\n5,5,5,5\n5,5,5,5\n")
    with pytest.raises(
        InputError,
        match=r"different frame sizes: visible 64x48 .* vs infrared 32x24 .*--align resize",
    ):
        open_sequence(root)
    seq = open_sequence(root, align="resize")
    assert seq.frame(1).infrared.shape == (48, 64)
    np.testing.assert_allclose(
        seq.truth.boxes["infrared"][1][0], [10, 10, 10, 10]
    )  # truth scaled too


def test_unreadable_frame_reported_at_its_frame(tmp_path):
    root = _rgbt234(tmp_path / "s")
    (root / "visible" / "00004v.jpg").write_bytes(b"not a jpeg")
    seq = open_sequence(root)
    it = seq.frames()
    for _ in range(3):
        next(it)
    with pytest.raises(InputError, match=r"unreadable frame 4: .*00004v.jpg"):
        next(it)


def test_later_frame_of_other_size(tmp_path):
    root = _rgbt234(tmp_path / "s")
    cv2.imwrite(str(root / "infrared" / "00003i.jpg"), np.zeros((40, 64), np.uint8))
    with pytest.raises(InputError, match=r"frame 3: infrared frame is 64x40, expected 64x48"):
        list(open_sequence(root).frames())


def test_malformed_truth_names_file_and_line(tmp_path):
    root = _rgbt234(tmp_path / "s")
    (root / "visible.txt").write_text("10,10,10,10\n11,10,10\n")
    with pytest.raises(InputError, match=r"visible.txt:2: malformed ground truth"):
        open_sequence(root)


@pytest.mark.parametrize("half, channel", [("visible", "visible"), ("infrared", "infrared")])
def test_one_half_of_a_two_channel_layout_is_a_one_channel_sequence(tmp_path, half, channel):
    root = _rgbt234(tmp_path / "s")
    other = "infrared" if half == "visible" else "visible"
    import shutil

    shutil.rmtree(root / other)
    (root / f"{other}.txt").unlink()
    seq = open_sequence(root)
    assert seq.layout == "rgbt234" and seq.channels == (channel,)
    np.testing.assert_allclose(seq.truth.primary()[1][0], TRUTH0)
    with pytest.raises(InputError, match=f"holds only {channel} frames"):
        open_sequence(root, channel=other)


def test_ir_folder_alone_is_read_by_the_layout_whose_truth_is_there(tmp_path):
    root = _vtuav(tmp_path / "s")
    import shutil

    shutil.rmtree(root / "rgb")
    (root / "rgb.txt").unlink()
    seq = open_sequence(root)
    assert seq.layout == "vtuav" and seq.channels == ("infrared",)
    assert np.isnan(seq.truth.primary()[1][1]).all()  # sparse truth: frame 2 has none


def test_vtuav_bus1_reads_its_boxes_every_tenth_frame(realdata):
    seq = open_sequence(realdata / "vtuav-bus1")
    assert (
        seq.layout == "vtuav"
        and seq.channels == ("visible", "infrared")
        and (seq.width, seq.height) == (1920, 1080)
    )
    vis, ir = seq.truth.boxes["visible"][1], seq.truth.boxes["infrared"][1]
    annotated = np.nonzero(~np.isnan(vis[:, 0]))[0] + 1
    assert annotated.tolist() == list(range(1, 102, 10))
    np.testing.assert_allclose(vis[0], [585, 94, 66, 83])  # rgb.txt row 1, "x y w h"
    np.testing.assert_allclose(vis[100], [621, 170, 69, 96])
    np.testing.assert_allclose(ir[10], [587, 106, 67, 68])
    assert resolve_init(seq)[0].box == BBox(585, 94, 66, 83)


def test_a_video_pair_with_vtuav_truth_reads_it_sparse_as_the_folder_does(tmp_path):
    """VTUAV's ``rgb.txt`` / ``ir.txt`` beside a video pair are one row every 10th frame, as in
    the image layout: rows on frames 1, 11, 21, not 1, 2, 3 (and no warning about row counts)."""
    folder = open_sequence(_vtuav(tmp_path / "images"))
    root = tmp_path / "videos"
    root.mkdir()
    for name, src in (("visible", "rgb"), ("infrared", "ir")):
        vw = cv2.VideoWriter(
            str(root / f"{name}.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48), True
        )
        for fp in folder.frames():
            img = fp.visible if src == "rgb" else cv2.cvtColor(fp.infrared, cv2.COLOR_GRAY2BGR)
            vw.write(img)
        vw.release()
        (root / f"{src}.txt").write_text((folder.path / f"{src}.txt").read_text())
    video = open_sequence(root)
    assert video.layout == "video-pair" and video.n_frames == folder.n_frames == 25
    assert video.truth.sparse_every == folder.truth.sparse_every == 10
    for ch in ("visible", "infrared"):
        np.testing.assert_array_equal(video.truth.boxes[ch][1], folder.truth.boxes[ch][1])
    assert (~np.isnan(video.truth.primary()[1][:, 0])).nonzero()[0].tolist() == [0, 10, 20]
    assert not video.warnings
