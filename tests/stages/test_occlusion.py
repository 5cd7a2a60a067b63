"""The paper's occlusion grading on hand-built d/area sequences."""

import numpy as np
import pytest

from pipeline.stages.motion import fit_linear_motion
from pipeline.stages.occlusion import (
    AreaReference,
    Grade,
    OcclusionConfig,
    grade_occlusion,
    is_lost,
    next_severe_run,
)

CFG = OcclusionConfig()


def test_grades_by_distance_then_area():
    ref = AreaReference()
    for a in (1000, 900, 1100, 950):
        ref = ref.add(a, CFG)
    m = ref.min_area(CFG)
    assert m == pytest.approx(0.4 * 900)
    seq = [(0.1, 1000), (0.39, 500), (0.4, 500), (0.7, 361), (0.7, 359), (0.2, 950)]
    assert [grade_occlusion(d, a, m, CFG) for d, a in seq] == [
        Grade.NONE,
        Grade.NONE,
        Grade.PARTIAL,
        Grade.PARTIAL,
        Grade.SEVERE,
        Grade.NONE,
    ]


def test_size_change_counts_as_occlusion():
    assert grade_occlusion(0.1, 2100, 300, CFG, predicted_area_px2=1000) == Grade.PARTIAL
    assert grade_occlusion(0.1, 1900, 300, CFG, predicted_area_px2=1000) == Grade.NONE


def test_reference_uses_only_the_first_frames():
    cfg = OcclusionConfig(reference_frames=3)
    ref = AreaReference()
    for a in (500, 400, 450, 10, 5):
        ref = ref.add(a, cfg)
    assert ref.areas == (500, 400, 450) and ref.min_area(cfg) == pytest.approx(160)
    assert AreaReference().min_area(cfg) is None


def test_lost_after_k0_consecutive_severe_frames():
    cfg = OcclusionConfig(max_severe_frames=3)
    run, lost_at = 0, None
    grades = [
        Grade.SEVERE,
        Grade.SEVERE,
        Grade.PARTIAL,
        Grade.SEVERE,
        Grade.SEVERE,
        Grade.SEVERE,
        Grade.SEVERE,
    ]
    for i, g in enumerate(grades):
        run = next_severe_run(g, run)
        if lost_at is None and is_lost(run, cfg):
            lost_at = i
    assert (
        lost_at == 6
    )  # a partial frame resets the count; the 4th consecutive severe frame loses the target


def test_linear_fit_recovers_planted_motion():
    rng = np.random.default_rng(0)
    t = np.arange(10, 26, dtype=float)
    hist = np.column_stack(
        [
            t,
            5 + 1.25 * t + rng.normal(0, 1.5, t.size),
            80 - 0.5 * t + rng.normal(0, 1.5, t.size),
            np.full(t.size, 24.0),
            np.full(t.size, 56.0),
        ]
    )
    fit = fit_linear_motion(hist, 40)
    # slope standard error = 1.5 / sqrt(sum((t - mean t)^2)) = 0.081 px/frame: allow 3 sigma
    assert abs(fit.vx - 1.25) < 0.25 and abs(fit.vy + 0.5) < 0.25
    assert abs(fit.cx - (5 + 1.25 * 40)) < 8 and (fit.w, fit.h) == (24.0, 56.0)
    with pytest.raises(ValueError):
        fit_linear_motion(hist[:1], 40)


@pytest.mark.parametrize(
    "kw",
    [
        dict(distance_threshold=0),
        dict(min_area_fraction=1.5),
        dict(reference_frames=0),
        dict(max_severe_frames=0),
        dict(reacquire_distance=0.5),
        dict(max_area_growth=1.0),
    ],
)
def test_bad_config(kw):
    with pytest.raises(ValueError):
        OcclusionConfig(**kw)


def test_sampling_distance_falls_with_the_target_s_pixels_and_is_zero_for_one_colour():
    """Random colours drawn from 8 equally likely bins: the distance between the two checkerboard
    halves, over sqrt(2), goes as sqrt((K - 1) / (4 N_eff)): about 0.16 for an 8 x 16 px box (100
    pixels, fewer in effect under the kernel's weights), a quarter of that for a box of sixteen
    times the pixels; a box of one colour has none."""
    from pipeline.stages.camshift import Feature, sampling_distance
    from pipeline.types import BBox

    rng = np.random.default_rng(0)
    bins = rng.integers(0, 8, (200, 200)).astype(np.uint8)
    f = Feature(bins, np.ones(bins.shape, bool), 8)
    small = np.mean([sampling_distance(f, BBox(x, 10, 8, 16)) for x in range(10, 190, 12)])
    large = np.mean([sampling_distance(f, BBox(x, 40, 32, 64)) for x in range(10, 160, 30)])
    assert 0.1 < small < 0.2 and 0.025 < large < 0.05
    assert 3 < small / large < 5
    flat = Feature(np.full((60, 60), 3, np.uint8), np.ones((60, 60), bool), 8)
    assert sampling_distance(flat, BBox(10, 10, 20, 30)) == pytest.approx(0.0, abs=1e-6)


def test_a_camshift_window_is_measured_as_a_scale_of_the_last_box():
    """The last box moved to the window's centre and scaled by sqrt(area ratio), within 1 +-
    max_step; its aspect ratio kept whatever the window's."""
    from pipeline.trackers.kalman_camshift import scaled_like
    from pipeline.types import BBox

    last = BBox(0, 0, 20, 40)
    shrunk = scaled_like(BBox(50, 50, 20, 20), last, 0.01)  # a window on the torso: half the area
    assert shrunk.as_tuple() == pytest.approx((60 - 9.9, 60 - 19.8, 19.8, 39.6))
    same = scaled_like(BBox(10, 10, 40, 20), last, 0.01)  # same area, other aspect: size unchanged
    assert (same.w, same.h) == pytest.approx((20, 40))
    free = scaled_like(BBox(0, 0, 40, 80), last, 1.0)
    assert (free.w, free.h) == pytest.approx((40, 80))
