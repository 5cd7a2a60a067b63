"""Ground-truth parsing: separators, corner and polygon forms, bases, NaN rows, malformed lines."""

import math

import numpy as np
import pytest

from pipeline.errors import InputError
from pipeline.io.groundtruth import expand_sparse, parse_box_file, parse_mot_truth


def test_mixed_separators_ints_and_floats(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text("10,20,30,40\n11 21 31 41\n12\t22\t32.5\t42.25\n13, 23,\t33 ,43\n")
    a = parse_box_file(f)
    np.testing.assert_array_equal(
        a, [[10, 20, 30, 40], [11, 21, 31, 41], [12, 22, 32.5, 42.25], [13, 23, 33, 43]]
    )


def test_corners_and_base(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text("11 21 41 61\n")
    np.testing.assert_array_equal(parse_box_file(f, "xyxy", base=1.0), [[10, 20, 30, 40]])


def test_polygon_becomes_bounding_box(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text(
        "257.53,218.89,257.53,159,313.31,159,313.31,218.89\n"
    )  # a VOT axis-aligned polygon
    np.testing.assert_allclose(parse_box_file(f), [[257.53, 159, 313.31 - 257.53, 218.89 - 159]])


def test_absent_rows_are_nan(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text("0,0,0,0\nNaN,NaN,NaN,NaN\n1,2,3,4\n5,5,-1,4\n\n")
    a = parse_box_file(f)
    assert a.shape == (4, 4)
    assert np.isnan(a[0]).all() and np.isnan(a[1]).all() and np.isnan(a[3]).all()
    np.testing.assert_array_equal(a[2], [1, 2, 3, 4])


@pytest.mark.parametrize(
    "line, match",
    [
        (
            "1,2,3",
            r"gt.txt:2: malformed ground truth, expected 4 \(box\) or 8 \(polygon\) numbers, "
            r"got 3",
        ),
        ("1,2,x,4", r"gt.txt:2: malformed ground truth, 'x' is not a number"),
    ],
)
def test_malformed_line_names_file_and_line(tmp_path, line, match):
    f = tmp_path / "gt.txt"
    f.write_text(f"1,2,3,4\n{line}\n")
    with pytest.raises(InputError, match=match):
        parse_box_file(f)


def test_empty_file(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text("\n\n")
    with pytest.raises(InputError, match="empty"):
        parse_box_file(f)


def test_mot_truth(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text(
        "1,1,11,21,30,40,1,1,0.5\n1,2,51,21,30,40,1,1,1\n2,1,12,21,30,40,0,1,1\n3,2,53,21,30,40,1,1,0.25\n"
    )
    mt = parse_mot_truth(f, 3)
    assert list(mt.boxes) == [1, 2]
    np.testing.assert_array_equal(mt.boxes[1][0], [10, 20, 30, 40])
    assert np.isnan(mt.boxes[1][1]).all()  # flag 0 is ignored, as MOTChallenge does
    assert mt.visibility[2][2] == 0.25 and math.isnan(mt.boxes[2][1][0])


def test_sparse_expansion():
    a = np.arange(12, dtype=float).reshape(3, 4)
    e = expand_sparse(a, 25, 10)
    np.testing.assert_array_equal(e[[0, 10, 20]], a)
    assert np.isnan(e[1]).all() and e.shape == (25, 4)


def test_distractor_rows_are_not_truth_but_are_kept_as_distractors(tmp_path):
    f = tmp_path / "gt.txt"
    f.write_text(
        "1,1,11,21,30,40,1,1,1\n1,1001,61,21,20,10,0,8,1\n2,1001,63,21,20,10,0,8,1\n2,5,1,1,5,5,0,1,1\n"
    )
    mt = parse_mot_truth(f, 2)
    assert list(mt.boxes) == [1]  # flag 0 rows are not truth, whatever their class
    assert list(mt.distractors) == [
        1001
    ]  # class 8 (MOTChallenge's distractor) rows are kept apart
    np.testing.assert_array_equal(mt.distractors[1001], [[60, 20, 20, 10], [62, 20, 20, 10]])
