"""The colour extent: exact masks and histograms on tiny arrays, a planted stride recovered, leaks
refused."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.stages.extent import (
    ExtentConfig,
    colour_extent,
    surround_histogram,
    target_mask,
    trimmed_range,
)
from pipeline.types import BBox

EXACT = ExtentConfig(trim_fraction=0.0)


def person(shape=(80, 60), top=(20, 27), torso=(6, 12), legs_w=10, legs_h=14, background=None):
    """bins image: a torso of bin 1 (``torso`` w x h at ``top`` = (y, x)) over spread legs of bin
    2, ``legs_w`` wide; the rest ``background`` (default bin 0)."""
    bins = np.zeros(shape, np.int32) if background is None else background.copy()
    y, x = top
    w, h = torso
    bins[y : y + h, x : x + w] = 1
    lx = x + w // 2 - legs_w // 2
    bins[y + h : y + h + legs_h, lx : lx + 3] = 2  # left leg
    bins[y + h : y + h + legs_h, lx + legs_w - 3 : lx + legs_w] = 2  # right leg
    return bins


def test_surround_histogram_leaves_out_the_grown_box():
    bins = np.zeros((10, 10), np.int32)
    bins[4:6, 4:6] = 1
    bins[0, 0] = 2
    h = surround_histogram(bins, BBox(4, 4, 2, 2), 0.5, 3)  # grown box: rows / columns 3..6
    assert h == pytest.approx(np.array([83, 0, 1]) / 84)
    assert surround_histogram(bins, BBox(0, 0, 10, 10), 0.0, 3).sum() == 0.0


def test_target_mask_is_the_likelihood_ratio_test():
    bins = np.array([[0, 1, 2, 3]])
    q = np.array([0.5, 0.3, 0.2, 0.0])
    b = np.array([0.5, 0.1, 0.1, 0.3])
    assert target_mask(bins, q, b, 2.0).tolist() == [[0, 1, 1, 0]]
    assert target_mask(bins, q, b, 2.5).tolist() == [[0, 1, 0, 0]]


def test_a_planted_stride_is_recovered_from_the_standing_box():
    """The box the target was given when it stood (6 x 26, the torso's width) grows to its spread
    legs."""
    bins = person()
    q = np.array([0.0, 0.6, 0.4])
    e = colour_extent(bins, q, BBox(27, 20, 6, 26), EXACT)
    assert e is not None
    # torso x 27..33, legs from 25 to 35, rows 20..46
    assert (e.x, e.y, e.w, e.h) == pytest.approx((25, 20, 10, 26), abs=1)


def test_a_target_joined_to_a_background_of_its_colour_is_refused():
    """A wall of the shirt's colour touching the target runs out of the window: the colour cannot
    tell them apart."""
    bg = np.zeros((80, 60), np.int32)
    bg[:, 33:] = 1
    bg[0:5, 0:5] = 1  # some of the colour in the surround as well
    bins = person(background=bg)
    q = np.array([0.0, 0.6, 0.4])
    assert colour_extent(bins, q, BBox(27, 20, 6, 26), EXACT) is None


def test_too_few_target_pixels_or_too_large_a_change_is_refused():
    bins = person()
    q = np.array([0.0, 0.6, 0.4])
    assert (
        colour_extent(bins, q, BBox(27, 20, 6, 26), ExtentConfig(trim_fraction=0.0, max_ratio=1.7))
        is not None
    )
    assert (
        colour_extent(bins, q, BBox(27, 20, 6, 26), ExtentConfig(trim_fraction=0.0, max_ratio=1.6))
        is None
    )
    assert (
        colour_extent(bins, q, BBox(27, 18, 6, 30), ExtentConfig(trim_fraction=0.0, min_fill=0.95))
        is None
    )  # 156 px of 180
    assert colour_extent(np.zeros((80, 60), np.int32), q, BBox(27, 20, 6, 26), EXACT) is None


def test_a_target_at_the_frame_border_is_measured():
    """Reaching the region's edge where the frame ends is not a leak."""
    bins = np.zeros((40, 40), np.int32)
    bins[10:30, 0:8] = 1
    e = colour_extent(bins, np.array([0.0, 1.0]), BBox(0, 10, 6, 20), EXACT)
    assert e is not None and (e.x, e.w, e.h) == (0.0, 8.0, 20.0)


@pytest.mark.parametrize(
    "name,value",
    [
        ("gap_fraction", -0.1),
        ("likelihood_ratio", 0.5),
        ("window_fraction", 2.0),
        ("min_fill", 1.5),
        ("trim_fraction", 0.3),
        ("max_ratio", 1.0),
    ],
)
def test_declared_ranges_are_enforced(name, value):
    with pytest.raises(ValueError, match=f"extent.{name}"):
        ExtentConfig(**{name: value})


def test_trimmed_range_equals_numpys_percentiles_to_the_last_bit():
    rng = np.random.default_rng(0)
    for _ in range(500):
        counts = rng.integers(0, 8, rng.integers(1, 60))
        if counts.sum() == 0:
            continue
        values = np.repeat(np.arange(counts.size), counts)
        for trim in (0.01, 0.02, 0.1, 0.2):
            ref = tuple(float(v) for v in np.percentile(values, [100 * trim, 100 * (1 - trim)]))
            assert trimmed_range(counts, trim) == ref


def test_compiled_window_mask_equals_surround_histogram_and_target_mask():
    """colour_extent's one compiled pass is surround_histogram then target_mask on the window: the
    two documented steps and the kernel must not drift apart (same mask, pixel for pixel)."""
    from pipeline.stages.extent import _window_mask

    rng = np.random.default_rng(11)
    for _ in range(50):
        bins = rng.integers(0, 8, (40, 50)).astype(np.uint8)
        q = rng.random(8) * (rng.random(8) < 0.7)
        q /= max(q.sum(), 1e-12)
        box = BBox(rng.uniform(5, 30), rng.uniform(5, 20), rng.uniform(3, 15), rng.uniform(3, 15))
        s = surround_histogram(bins, box, 0.25, 8)
        x0, y0, x1, y1 = 2, 3, 45, 37
        ref = target_mask(bins[y0:y1, x0:x1], q, s, 2.0)
        gx, gy = 0.25 * box.w, 0.25 * box.h
        got = _window_mask(
            bins,
            q,
            max(int(np.floor(box.x - gx)), 0),
            max(int(np.floor(box.y - gy)), 0),
            min(int(np.ceil(box.x2 + gx)), 50),
            min(int(np.ceil(box.y2 + gy)), 40),
            x0,
            y0,
            x1,
            y1,
            2.0,
        )
        assert np.array_equal(got, ref)
