"""The paper's occlusion grading on hand-built d/area sequences."""

import numpy as np
import pytest

from pipeline.stages.motion import fit_linear_motion
from pipeline.stages.occlusion import AreaReference, Grade, OcclusionConfig, grade_occlusion, is_lost, next_severe_run

CFG = OcclusionConfig()


def test_grades_by_distance_then_area():
    ref = AreaReference()
    for a in (1000, 900, 1100, 950):
        ref = ref.add(a, CFG)
    m = ref.min_area(CFG)
    assert m == pytest.approx(0.4 * 900)
    seq = [(0.1, 1000), (0.39, 500), (0.4, 500), (0.7, 361), (0.7, 359), (0.2, 950)]
    assert [grade_occlusion(d, a, m, CFG) for d, a in seq] == [
        Grade.NONE, Grade.NONE, Grade.PARTIAL, Grade.PARTIAL, Grade.SEVERE, Grade.NONE]


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
    grades = [Grade.SEVERE, Grade.SEVERE, Grade.PARTIAL, Grade.SEVERE, Grade.SEVERE, Grade.SEVERE, Grade.SEVERE]
    for i, g in enumerate(grades):
        run = next_severe_run(g, run)
        if lost_at is None and is_lost(run, cfg):
            lost_at = i
    assert lost_at == 6  # a partial frame resets the count; the 4th consecutive severe frame loses the target


def test_linear_fit_recovers_planted_motion():
    rng = np.random.default_rng(0)
    t = np.arange(10, 26, dtype=float)
    hist = np.column_stack([t, 5 + 1.25 * t + rng.normal(0, 1.5, t.size), 80 - 0.5 * t + rng.normal(0, 1.5, t.size),
                            np.full(t.size, 24.0), np.full(t.size, 56.0)])
    fit = fit_linear_motion(hist, 40)
    # slope standard error = 1.5 / sqrt(sum((t - mean t)^2)) = 0.081 px/frame: allow 3 sigma
    assert abs(fit.vx - 1.25) < 0.25 and abs(fit.vy + 0.5) < 0.25
    assert abs(fit.cx - (5 + 1.25 * 40)) < 8 and (fit.w, fit.h) == (24.0, 56.0)
    with pytest.raises(ValueError):
        fit_linear_motion(hist[:1], 40)


@pytest.mark.parametrize("kw", [dict(distance_threshold=0), dict(min_area_fraction=1.5), dict(reference_frames=0),
                                dict(max_severe_frames=0), dict(reacquire_distance=0.5), dict(max_area_growth=1.0)])
def test_bad_config(kw):
    with pytest.raises(ValueError):
        OcclusionConfig(**kw)
