"""The contour stage: sub-pixel box, warm start, and each failure reason on hand-built IR
frames."""

import cv2
import numpy as np
import pytest

from pipeline.stages.contour import ContourConfig, _ring_contrast, _subpixel_box, extract_contour
from pipeline.stages.levelset import LevelSetConfig
from pipeline.types import BBox

LS = LevelSetConfig()


def _frame(objects, size=(200, 160), noise=2.0, seed=0):
    """IR frame (W, H) with filled rectangles (x, y, w, h, contrast), softened like a thermal
    image."""
    rng = np.random.default_rng(seed)
    img = np.full((size[1], size[0]), 95.0, np.float32)
    for x, y, w, h, c in objects:
        m = np.zeros_like(img)
        cv2.rectangle(m, (x * 4, y * 4), ((x + w) * 4 - 1, (y + h) * 4 - 1), 1.0, -1, shift=2)
        img += c * cv2.GaussianBlur(m, (0, 0), 1.0)
    return np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)


def test_subpixel_box_of_a_planted_target():
    ir = _frame([(80, 50, 24, 56, 60)])
    c = extract_contour(ir, BBox(78, 48, 28, 60), ContourConfig(), LS)
    assert c.ok and c.reason == "ok" and c.contrast > 40
    np.testing.assert_allclose(
        c.box.as_tuple(), (80, 50, 24, 56), atol=1.5
    )  # thermal blur softens the edges
    assert c.contour and c.contour[0].shape[1] == 2


def test_subpixel_edges_at_the_interpolated_zero_crossings():
    # phi = |col - 5| - 2.3 on rows 4..11, +1 elsewhere: inside columns 3..7, zero crossings at
    # column indices 2.7 and 7.3, i.e. x = 3.2 and 7.8 in pixel-corner coordinates; on the top and
    # bottom rows the farthest crossing is in column 5 (phi -2.3 inside, +1 outside: 2.3/3.3 of a
    # pixel out)
    phi = np.ones((16, 12), np.float32)
    phi[4:12] = np.abs(np.arange(12) - 5.0) - 2.3
    x0, y0, x1, y1 = _subpixel_box(phi, phi < 0)
    assert (x0, x1) == pytest.approx((3.2, 7.8), abs=1e-6)
    top_frac = 2.3 / 3.3
    assert (y0, y1) == pytest.approx((4.5 - top_frac, 11.5 + top_frac), abs=1e-6)
    edge = np.ones((6, 6), np.float32)
    edge[:, :3] = -1  # the mask touches the array's left edge: half a pixel beyond the last centre
    assert _subpixel_box(edge, edge < 0)[0] == 0.0


def test_ring_contrast_equals_the_numpy_route():
    rng = np.random.default_rng(5)
    for k in range(300):
        h, w = rng.integers(2, 70, 2)
        roi = rng.integers(0, 256, (h, w), dtype=np.uint8)
        sel = (cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), 2.0) > 0.2 * (k % 3)).astype(
            np.uint8
        )
        if not sel.any():
            continue
        ring = cv2.dilate(sel, np.ones((7, 7), np.uint8)).astype(bool) & ~sel.astype(bool)
        roi_f = roi.astype(np.float32)
        ref = float(roi_f[sel.astype(bool)].mean() - roi_f[ring].mean()) if ring.any() else 0.0
        assert _ring_contrast(roi, sel) == ref
    whole = np.ones((5, 5), np.uint8)  # no ring: nothing to compare with
    assert _ring_contrast(np.full((5, 5), 9, np.uint8), whole) == 0.0


def test_warm_start_tracks_the_displacement():
    ir = _frame([(80, 50, 24, 56, 60)])
    first = extract_contour(ir, BBox(80, 50, 24, 56), ContourConfig(), LS)
    ir2 = _frame([(86, 47, 24, 56, 60)], seed=1)
    c = extract_contour(ir2, BBox(86, 47, 24, 56), ContourConfig(), LS, first.memory, (6.0, -3.0))
    assert c.warm and c.ok
    np.testing.assert_allclose(
        c.box.as_tuple(), (86, 47, 24, 56), atol=2.0
    )  # blur sigma 1 px + noise


def test_no_component_on_a_flat_frame():
    c = extract_contour(_frame([]), BBox(80, 50, 24, 56), ContourConfig(), LS)
    assert not c.ok and c.reason in ("no-component", "collapse", "low-contrast")


def test_low_contrast_target_is_reported():
    c = extract_contour(
        _frame([(80, 50, 24, 56, 7)], noise=0.5), BBox(80, 50, 24, 56), ContourConfig(), LS
    )
    assert (
        c.box is not None
        and c.reason == "low-contrast"
        and abs(c.contrast) < ContourConfig().min_contrast
    )


def test_hotter_neighbour_is_cut_off_at_the_edge_between():
    ir = _frame([(80, 50, 24, 56, 60), (104, 40, 50, 70, 80)])
    c = extract_contour(ir, BBox(80, 50, 24, 56), ContourConfig(), LS)
    assert c.ok
    np.testing.assert_allclose(c.box.as_tuple(), (80, 50, 24, 56), atol=2.0)


def test_merged_neighbour_of_the_same_heat_is_too_large():
    # started over both (as when two targets merged), with no edge between them: one blob, far too
    # large
    ir = _frame([(80, 50, 24, 56, 60), (104, 40, 40, 70, 60)])
    c = extract_contour(
        ir,
        BBox(80, 50, 24, 56),
        ContourConfig(roi_margin_fraction=1.5),
        LS,
        cold_init=BBox(74, 34, 76, 82),
    )
    assert not c.ok and c.reason in (
        "too-large",
        "shape-change",
        "leak",
    )  # the blob runs past the region: a leak


def test_two_objects_are_two_components():
    from pipeline.stages.contour import LevelSetMemory, region
    from pipeline.stages.levelset import box_step

    ir = _frame([(60, 50, 24, 56, 60), (110, 50, 24, 56, 60)])
    expected = BBox(55, 45, 84, 66)
    x0, y0, x1, y1 = region(expected, ContourConfig(), 200, 160)
    phi = np.minimum(
        box_step((y1 - y0, x1 - x0), (60 - 3 - x0, 50 - 3 - y0, 30, 62), 2.0),
        box_step((y1 - y0, x1 - x0), (110 - 3 - x0, 50 - 3 - y0, 30, 62), 2.0),
    )
    c = extract_contour(
        ir,
        expected,
        ContourConfig(max_area_ratio=3.0),
        LS,
        LevelSetMemory(phi, (x0, y0)),
        part_width=24,
    )
    assert len(c.components) == 2
    np.testing.assert_allclose(sorted(b.x for b in c.components), [60, 110], atol=2.0)


@pytest.mark.parametrize(
    "kw",
    [
        dict(roi_margin_px=1),
        dict(cold_start_scale=3),
        dict(max_area_ratio=1),
        dict(min_area_fraction=0),
        dict(closing_fraction=2),
        dict(max_dimension_ratio=0.5),
    ],
)
def test_bad_config(kw):
    with pytest.raises(ValueError):
        ContourConfig(**kw)
