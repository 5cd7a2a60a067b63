"""Mean shift: a planted shift is recovered within 1 px; scale search prefers the true size."""

import numpy as np
import pytest

from pipeline.stages.histogram import HistogramConfig, appearance_bins, kernel_histogram
from pipeline.stages.meanshift import MeanShiftConfig, mean_shift, mean_shift_scale_search
from pipeline.types import BBox


def _scene(cx, cy, w=24, h=40, size=(160, 120), seed=0):
    """A two-coloured textured target on a textured background (BGR)."""
    rng = np.random.default_rng(seed)
    W, H = size
    img = rng.integers(60, 120, (H, W, 3), dtype=np.uint8)
    img[..., 1] = rng.integers(90, 140, (H, W))
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    inside = (np.abs(xx - cx) < w / 2) & (np.abs(yy - cy) < h / 2)
    top = inside & (yy < cy)
    img[top] = (40, 40, 210)
    img[inside & ~top] = (150, 60, 30)
    img[inside] = np.clip(
        img[inside].astype(int) + rng.integers(-15, 15, (inside.sum(), 3)), 0, 255
    )
    return img.astype(np.uint8)


@pytest.mark.parametrize("dx, dy", [(0, 0), (6, -4), (-9, 7), (12, 10)])
def test_planted_shift_recovered_within_1px(dx, dy):
    cfg = HistogramConfig()
    model_img = _scene(80, 60)
    bins0, m = appearance_bins(model_img, cfg)
    q = kernel_histogram(bins0, BBox.from_center(80, 60, 24, 40), m)
    moved = _scene(80 + dx, 60 + dy, seed=1)
    bins1, _ = appearance_bins(moved, cfg)
    r = mean_shift(bins1, q, (80.0, 60.0), (12.0, 20.0), MeanShiftConfig())
    assert r.converged and not r.no_support
    assert np.hypot(r.center[0] - (80 + dx), r.center[1] - (60 + dy)) < 1.0
    assert r.rho > 0.8


def test_no_model_colour_is_reported_not_raised():
    q = np.zeros(256)
    q[13 * 16 + 15] = 1.0  # saturated magenta: nowhere in the image
    bins, _ = appearance_bins(_scene(80, 60), HistogramConfig())
    r = mean_shift(bins, q, (80.0, 60.0), (12.0, 20.0), MeanShiftConfig())
    assert r.no_support and r.center == (80.0, 60.0)


def test_scale_search_prefers_true_size():
    cfg = HistogramConfig()
    img = _scene(80, 60)
    bins, m = appearance_bins(img, cfg)
    q = kernel_histogram(bins, BBox.from_center(80, 60, 24, 40), m)
    big = mean_shift_scale_search(bins, q, (80.0, 60.0), (12 * 1.1, 20 * 1.1), MeanShiftConfig())
    assert big.best_factor < 1.0  # a window 10 % too large shrinks


def test_iteration_callback_and_cap():
    cfg = HistogramConfig()
    img = _scene(80, 60)
    bins, m = appearance_bins(img, cfg)
    q = kernel_histogram(bins, BBox.from_center(80, 60, 24, 40), m)
    seen = []
    r = mean_shift(
        bins,
        q,
        (70.0, 55.0),
        (12.0, 20.0),
        MeanShiftConfig(max_iterations=2),
        iter_callback=seen.append,
    )
    assert r.iterations == 2 == len(seen) and [s.iteration for s in seen] == [1, 2]


@pytest.mark.parametrize(
    "kw", [dict(max_iterations=0), dict(epsilon_px=0), dict(scale_step=0.7), dict(scale_rate=2)]
)
def test_bad_config(kw):
    with pytest.raises(ValueError):
        MeanShiftConfig(**kw)


@pytest.mark.parametrize(
    "dx, dy, seed", [(0, 0, 1), (6, -4, 2), (-9, 7, 3), (12, 10, 4), (30, 25, 5)]
)
def test_compiled_loop_equals_the_python_loop_to_the_last_bit(dx, dy, seed):
    """Without a callback the loop runs compiled; with one, in Python: the same result, bit for
    bit (centre, rho, histogram, iterations, halvings, mass), including a start far off."""
    cfg = HistogramConfig()
    bins0, m = appearance_bins(_scene(80, 60), cfg)
    q = kernel_histogram(bins0, BBox.from_center(80, 60, 24, 40), m)
    bins1, _ = appearance_bins(_scene(80 + dx, 60 + dy, seed=seed), cfg)
    ms = MeanShiftConfig(max_iterations=6)
    fast = mean_shift(bins1, q, (80.0, 60.0), (12.0, 20.0), ms)
    slow = mean_shift(bins1, q, (80.0, 60.0), (12.0, 20.0), ms, iter_callback=lambda it: None)
    assert fast.center == slow.center and fast.rho == slow.rho
    assert (fast.iterations, fast.converged, fast.halvings) == (
        slow.iterations,
        slow.converged,
        slow.halvings,
    )
    assert fast.mass_fraction == slow.mass_fraction and fast.no_support == slow.no_support
    assert np.array_equal(fast.p, slow.p)
