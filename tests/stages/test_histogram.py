"""Bin images, kernel histograms and the Bhattacharyya coefficient on tiny arrays."""

import cv2
import numpy as np
import pytest

from pipeline.stages.histogram import (
    HistogramConfig,
    _luts,
    bhattacharyya,
    bhattacharyya_distance,
    bright_fraction,
    hsv_bin_image,
    intensity_bin_image,
    kernel_histogram,
    kernel_window,
    search_roi,
)
from pipeline.types import BBox

CFG = HistogramConfig()


def test_hsv_bins_exact():
    # one pixel per known HSV value (OpenCV 8-bit HSV: H 0..179)
    hsv = np.array([[[0, 0, 0], [179, 255, 255], [90, 128, 64], [45, 63, 192]]], np.uint8)
    bgr = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)
    back = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)  # what the stage will see after the round trip
    h, s, v = back[0, :, 0].astype(int), back[0, :, 1].astype(int), back[0, :, 2].astype(int)
    expect = (h * 16 // 180) * 16 + (s * 4 // 256) * 4 + v * 4 // 256
    np.testing.assert_array_equal(hsv_bin_image(bgr, CFG)[0], expect)
    assert hsv_bin_image(bgr, CFG).max() < CFG.hsv_bins == 256


@pytest.mark.parametrize(
    "cfg",
    [
        CFG,
        HistogramConfig(hue_bins=8, saturation_bins=8, value_bins=4),
        HistogramConfig(value_bins=1),
    ],
)
def test_compiled_bin_sum_equals_the_opencv_route(cfg):
    # every 8-bit HSV triple the conversion can give, through split + three LUTs + two saturating
    # adds
    h, s, v = np.meshgrid(
        np.arange(180), np.arange(0, 256, 5), np.arange(0, 256, 5), indexing="ij"
    )
    bgr = cv2.cvtColor(
        np.stack([h, s, v], -1).reshape(180, -1, 3).astype(np.uint8), cv2.COLOR_HSV2BGR
    )
    hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
    lh, ls, lv = _luts(cfg)
    ch = cv2.split(hsv)
    ref = cv2.add(cv2.add(cv2.LUT(ch[0], lh), cv2.LUT(ch[1], ls)), cv2.LUT(ch[2], lv))
    np.testing.assert_array_equal(hsv_bin_image(bgr, cfg), ref)
    np.testing.assert_array_equal(
        hsv_bin_image(bgr[:, 5:40], cfg), ref[:, 5:40]
    )  # a non-contiguous crop


def test_bright_fraction_counts_the_hsv_value():
    rng = np.random.default_rng(4)
    frame = rng.integers(0, 256, (60, 80, 3), dtype=np.uint8)
    for y0, y1, x0, x1, v in (
        (0, 60, 0, 80, 40),
        (5, 17, 30, 41, 200),
        (3, 4, 3, 4, 0),
        (10, 30, 10, 30, 256),
    ):
        patch = frame[y0:y1, x0:x1]
        assert (
            bright_fraction(patch, v)
            == np.count_nonzero(patch.max(axis=2) >= v) / patch[..., 0].size
        )
    assert bright_fraction(np.array([[[10, 50, 5], [39, 39, 39]]], np.uint8), 40) == 0.5
    assert bright_fraction(frame[:0], 40) == 0.0


def test_intensity_bins_exact():
    g = np.array([[0, 7, 8, 255]], np.uint8)
    np.testing.assert_array_equal(intensity_bin_image(g, CFG), [[0, 0, 1, 31]])


def test_kernel_window_epanechnikov_weights():
    win = kernel_window((10, 10), 5.0, 5.0, 2.0, 2.0)
    # pixel centres (4.5, 4.5): r^2 = 2*(0.25^2) = 0.125 -> k = 0.875
    i = np.where((win.rows == 4) & (win.cols == 4))[0][0]
    assert win.k[i] == pytest.approx(0.875)
    assert (win.k > 0).all() and win.mass_fraction == pytest.approx(1.0, abs=0.03)
    cut = kernel_window((10, 10), 0.0, 5.0, 2.0, 2.0)  # half the ellipse outside the image
    assert cut.mass_fraction == pytest.approx(0.5, abs=0.05)


def test_histogram_normalized_and_rho_identity():
    rng = np.random.default_rng(0)
    bins = rng.integers(0, 32, (40, 40)).astype(np.int32)
    p = kernel_histogram(bins, BBox(5, 5, 20, 16), 32)
    assert p.sum() == pytest.approx(1.0) and (p >= 0).all()
    assert bhattacharyya(p, p) == pytest.approx(1.0)
    q = kernel_histogram(bins, BBox(15, 18, 20, 16), 32)
    d_cv = cv2.compareHist(p.astype(np.float32), q.astype(np.float32), cv2.HISTCMP_BHATTACHARYYA)
    assert bhattacharyya_distance(bhattacharyya(p, q)) == pytest.approx(d_cv, abs=1e-5)
    assert bhattacharyya(np.eye(4)[0], np.eye(4)[1]) == 0.0


def test_search_roi_clipped_and_never_empty():
    assert search_roi(BBox(10, 10, 10, 20), 1.0, 100, 100) == (0, 0, 30, 50)
    assert search_roi(BBox(200, 200, 10, 10), 1.0, 100, 100) == (99, 99, 100, 100)


@pytest.mark.parametrize("kw", [dict(hue_bins=1), dict(value_bins=0), dict(intensity_bins=300)])
def test_bad_config(kw):
    with pytest.raises(ValueError):
        HistogramConfig(**kw)


@pytest.mark.parametrize(
    "cx, cy, hx, hy", [(10.3, 7.8, 4.5, 6.2), (0.5, 0.5, 5.0, 3.0), (19.9, 14.2, 8.0, 9.0)]
)
def test_compiled_ellipse_equals_the_window_route(cx, cy, hx, hy):
    """The compiled one-pass histogram and mean-shift sums equal kernel_window + bincount exactly,
    including windows cut by the image border."""
    from pipeline.stages.histogram import (
        ellipse_histogram,
        ellipse_model,
        ellipse_shift,
        window_histogram,
    )

    bins = np.random.default_rng(3).integers(0, 8, (16, 20)).astype(np.int32)
    win = kernel_window(bins.shape, cx, cy, hx, hy)
    h, mass, n = ellipse_histogram(bins, cx, cy, hx, hy, 8)
    np.testing.assert_array_equal(
        h, np.bincount(bins[win.rows, win.cols], weights=win.k, minlength=8)
    )
    assert n == win.k.size and mass == pytest.approx(win.k.sum(), rel=1e-12)
    p, _n2, frac = ellipse_model(bins, cx, cy, hx, hy, 8)
    np.testing.assert_allclose(p, window_histogram(bins, win, 8), rtol=1e-12)
    assert frac == pytest.approx(win.mass_fraction, rel=1e-12)
    valid = (
        np.random.default_rng(4).random(bins.shape) < 0.7
    )  # CamShift's mask of pixels with colour
    ok = valid[win.rows, win.cols]
    hv, _, nv = ellipse_histogram(bins, cx, cy, hx, hy, 8, valid)
    np.testing.assert_array_equal(
        hv, np.bincount(bins[win.rows[ok], win.cols[ok]], weights=win.k[ok], minlength=8)
    )
    assert nv == int(ok.sum())
    w = np.linspace(0.1, 1.0, 8)
    sw, sx, sy = ellipse_shift(bins, w, cx, cy, hx, hy)
    ww = w[bins[win.rows, win.cols]]
    assert (sw, sx, sy) == pytest.approx((ww.sum(), ww @ win.xs, ww @ win.ys), rel=1e-12)


def test_compiled_sum_is_numpys_to_the_last_bit():
    """The compiled pairwise sum (histogram normalisation, Bhattacharyya) adds as numpy does:
    the same float64 on every length from 0 to 1100 and on long arrays, where a plain running
    sum differs."""
    from pipeline.stages.histogram import np_sum

    rng = np.random.default_rng(7)
    differs = 0
    for n in [*range(0, 1100), 4096, 20000]:
        a = rng.random(n) * rng.choice([1e-3, 1.0, 1e5])
        a[rng.random(n) < 0.4] = 0.0
        assert np_sum(a) == np.sum(a)
        running = 0.0
        for v in a:
            running += v
        differs += running != np.sum(a)
    assert differs > 100  # the order matters: the test could tell a plain sum apart
