"""A moving camera noticed: :func:`registration` and the sequence background's ``holds``."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pipeline.stages.detection import (
    DetectionConfig,
    quantile_background,
    registration,
)


def world(rng: np.random.Generator, shape=(440, 720)) -> np.ndarray:
    """A wide textured IR scene: speckle plus blocks of +-50 grey levels (walls, windows)."""
    w = cv2.GaussianBlur(rng.normal(90, 25, shape), (0, 0), 2).astype(np.float32)
    for _ in range(60):
        y, x = rng.integers(0, shape[0] - 40), rng.integers(0, shape[1] - 40)
        w[y : y + rng.integers(8, 40), x : x + rng.integers(8, 40)] += rng.uniform(-50, 50)
    return w


def view(w: np.ndarray, ox: float, oy: float, rng, shape=(240, 320)) -> np.ndarray:
    """The camera's 320 x 240 view of ``w`` from (ox, oy), with sensor noise."""
    m = np.float32([[1, 0, -ox], [0, 1, -oy]])
    img = cv2.warpAffine(w, m, (shape[1], shape[0]), flags=cv2.INTER_LINEAR)
    return img + rng.normal(0, 2, img.shape).astype(np.float32)


@pytest.mark.parametrize("pan", [(12.0, 0.0), (-30.0, 5.0), (0.0, -20.0), (45.0, 10.0)])
def test_a_view_panned_beyond_the_shake_is_seen_from_elsewhere(pan):
    rng = np.random.default_rng(1)
    w = world(rng)
    ref, img = view(w, 100, 80, rng), view(w, 100 + pan[0], 80 + pan[1], rng)
    shift, moved = registration(ref, img, 4.0)
    assert moved
    assert max(abs(shift[0]), abs(shift[1])) <= 4.0  # the shift itself stays within the shake


@pytest.mark.parametrize("shake", [(0.0, 0.0), (2.5, -1.0), (-3.5, 3.0)])
def test_a_shaken_view_is_not_moved_and_its_shift_is_recovered(shake):
    rng = np.random.default_rng(2)
    w = world(rng)
    ref, img = view(w, 100, 80, rng), view(w, 100 - shake[0], 80 - shake[1], rng)
    shift, moved = registration(ref, img, 4.0)
    assert not moved and shift == pytest.approx(shake, abs=0.4)


def test_a_large_warm_target_crossing_a_weakly_textured_still_view_is_not_a_moving_camera():
    """The target's own displacement can be the correlation's highest peak (checked below), but
    carrying the whole view there does not make the frames agree."""
    rng = np.random.default_rng(3)
    ground = cv2.GaussianBlur(rng.normal(90, 6, (240, 320)), (0, 0), 6).astype(np.float32)
    a, b = ground.copy(), ground.copy()
    cv2.ellipse(a, (80, 140), (14, 36), 0, 0, 360, 230, -1)
    cv2.ellipse(b, (130, 140), (14, 36), 0, 0, 360, 230, -1)
    a += rng.normal(0, 2, a.shape).astype(np.float32)
    b += rng.normal(0, 2, b.shape).astype(np.float32)
    (gx, _), _ = cv2.phaseCorrelate(a.astype(np.float64), b.astype(np.float64))
    assert gx > 40  # the global peak is the target's 50 px
    assert registration(a, b, 4.0)[1] is False


def test_the_background_of_a_panning_camera_does_not_hold_and_a_still_ones_does():
    rng = np.random.default_rng(4)
    w = world(rng)
    panned = [view(w, 40 + 6 * k, 60 + k, rng) for k in range(25)]
    shaken = [view(w, 100 + rng.uniform(-2, 2), 80 + rng.uniform(-2, 2), rng) for _ in range(25)]
    cfg = DetectionConfig()
    moving, still = quantile_background(panned, cfg), quantile_background(shaken, cfg)
    assert moving.moved_samples >= 20 and not moving.holds
    assert still.moved_samples == 0 and still.holds
