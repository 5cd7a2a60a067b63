"""Initial targets: --init, --init-file, first-frame truth; clipping and errors."""

import pytest

from pipeline.errors import InputError
from pipeline.io.init import parse_box_arg, resolve_init
from pipeline.io.sequence import open_sequence
from pipeline.types import BBox, InitTarget
from tests.conftest import write_boxes, write_frames


@pytest.fixture()
def seq(tmp_path):
    root = tmp_path / "s"
    write_frames(root / "visible", 3)
    write_frames(root / "infrared", 3, color=False)
    write_boxes(root / "visible.txt", 3)
    return open_sequence(root)


def test_init_args_take_precedence(seq, tmp_path):
    t = resolve_init(seq, ["1,2,10,12", "30 20 5 6"])
    assert [(x.id, x.box) for x in t] == [(1, BBox(1, 2, 10, 12)), (2, BBox(30, 20, 5, 6))]


def test_init_file_plain_and_mot(seq, tmp_path):
    f = tmp_path / "init.txt"
    f.write_text("1,2,10,12\n3,4,5,6\n")
    assert [x.box for x in resolve_init(seq, None, f)] == [BBox(1, 2, 10, 12), BBox(3, 4, 5, 6)]
    f.write_text(
        "1,5,2,3,10,12,1,-1,-1,-1\n2,5,3,2,10,12,1,-1,-1,-1\n1,9,21,21,5,5,1,-1,-1,-1\n"
    )  # MOT rows: 1-based
    assert [(x.id, x.box) for x in resolve_init(seq, None, f)] == [
        (5, BBox(1, 2, 10, 12)),
        (9, BBox(20, 20, 5, 5)),
    ]


def test_truth_is_the_fallback(seq):
    assert resolve_init(seq) == resolve_init(seq, [])
    assert resolve_init(seq)[0].box == BBox(10, 10, 10, 10)


def test_partly_outside_is_clipped_fully_outside_is_an_error(seq):
    assert resolve_init(seq, ["-5,-5,10,10"])[0].box == BBox(0, 0, 5, 5)
    with pytest.raises(InputError, match=r"init box of target 1 .* lies outside the 64x48 frame"):
        resolve_init(seq, ["100,10,10,10"])
    with pytest.raises(InputError, match="positive width and height"):
        resolve_init(seq, ["1,1,0,5"])
    with pytest.raises(InputError, match="expected four numbers"):
        parse_box_arg("1,2,3")


def test_no_truth_no_init_is_a_clear_error(tmp_path):
    root = tmp_path / "s"
    write_frames(root / "visible", 2)
    write_frames(root / "infrared", 2, color=False)
    with pytest.raises(InputError, match=r"no initial target .* give --init"):
        resolve_init(open_sequence(root))


def test_an_init_file_of_several_boxes_says_which_convention_it_was_read_by(tmp_path):
    """A one-channel folder whose only truth is a many-line ``init.txt``: RGBT234's convention
    (one target, a box per frame), said in a warning that names ``--init-file`` for several."""
    root = tmp_path / "seq"
    write_frames(root / "visible", 3)
    (root / "init.txt").write_text("10,10,10,10\n11,10,10,10\n40,20,8,8\n")
    seq = open_sequence(root)
    assert resolve_init(seq) == [InitTarget(1, BBox(10, 10, 10, 10))]
    assert any("one target's box per frame" in w and "--init-file" in w for w in seq.warnings)
