"""ROI correlation: ECC recovers a planted affine warp; GAT gets close; chips and likelihoods."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from pipeline.stages.roi_match import (
    RoiMatchConfig,
    chip,
    ecc_match,
    gat_match,
    image_likelihood,
    match_boxes,
    ncc,
    roi_chips,
)

P = 10


def planted(angle_deg: float, scale: float, tx: float, ty: float, sigma: float = 4.0):
    """Template f (60x60) from a smooth random texture and g (80x80) = f under the affine map M
    (about f's centre) shifted by P, i.e. g(M x) = f(x)."""
    rng = np.random.default_rng(0)
    big = cv2.GaussianBlur(rng.normal(128, 40, (200, 200)).astype(np.float32), (0, 0), sigma)
    f = big[70:130, 70:130].copy()
    a = math.radians(angle_deg)
    c = np.array([29.5, 29.5])
    A = scale * np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    M = np.hstack([A, (np.array([tx, ty]) + c - A @ c + P)[:, None]])
    Minv = np.linalg.inv(np.vstack([M, [0, 0, 1]]))
    T = (np.array([[1, 0, 70], [0, 1, 70], [0, 0, 1.0]]) @ Minv)[:2].astype(np.float32)
    g = cv2.warpAffine(
        big, T, (60 + 2 * P, 60 + 2 * P), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    )
    return f, g, M


def centre_and_rotation(W: np.ndarray) -> tuple[np.ndarray, float]:
    c = np.array([29.5, 29.5])
    return W[:, :2] @ c + W[:, 2], math.degrees(math.atan2(W[1, 0], W[0, 0]))


@pytest.mark.parametrize(
    "warp", [(8.0, 1.05, 2.3, -1.7), (-12.0, 0.93, -3.0, 2.5), (0.0, 1.0, 1.4, 0.6)]
)
def test_ecc_recovers_a_planted_affine_warp(warp):
    f, g, M = planted(*warp)
    m = ecc_match(f, g, RoiMatchConfig(), np.array([[1, 0, P], [0, 1, P]], np.float32))
    assert m.converged and m.correlation > 0.99
    (c, rot), (c_true, rot_true) = centre_and_rotation(m.warp), centre_and_rotation(M)
    assert np.abs(c - c_true).max() <= 0.5
    assert abs(rot - rot_true) <= 1.0


def test_gat_route_gets_close_and_scores_with_ncc():
    f, g, M = planted(8.0, 1.05, 2.3, -1.7)
    m = gat_match(
        f,
        g,
        RoiMatchConfig(gat_iterations=8, gat_points=150),
        np.array([[1, 0, P], [0, 1, P]], np.float32),
    )
    (c, rot), (c_true, rot_true) = centre_and_rotation(m.warp), centre_and_rotation(M)
    assert m.correlation > 0.95 and np.abs(c - c_true).max() <= 1.0 and abs(rot - rot_true) <= 3.0


def test_failures_are_no_match_not_errors():
    flat = np.full((40, 40), 100, np.float32)
    rng = np.random.default_rng(1)
    tex = cv2.GaussianBlur(rng.normal(128, 40, (56, 56)).astype(np.float32), (0, 0), 3)
    m = ecc_match(flat, tex, RoiMatchConfig())
    assert not m.converged and math.isnan(m.correlation)
    paper = RoiMatchConfig(sharpness=0.0)
    assert image_likelihood(m.correlation, paper) == 0.01
    assert image_likelihood(-0.4, paper) == 0.01
    assert image_likelihood(0.83, paper) == pytest.approx(0.83)
    sharp = RoiMatchConfig(sharpness=20.0, likelihood_floor=1e-6)
    assert image_likelihood(0.97, sharp) == pytest.approx(math.exp(-0.6))
    assert math.log(
        image_likelihood(0.97, sharp) / image_likelihood(0.80, sharp)
    ) == pytest.approx(3.4)


def test_ncc_is_gain_and_offset_invariant():
    rng = np.random.default_rng(2)
    a = rng.normal(0, 1, (20, 20))
    assert ncc(a, 3 * a + 7) == pytest.approx(1.0)
    assert ncc(a, -a) == pytest.approx(-1.0)


def test_chips_sample_boxes_at_one_scale_and_match_a_moved_target():
    rng = np.random.default_rng(3)
    frame1 = cv2.GaussianBlur(rng.normal(60, 10, (120, 160)), (0, 0), 2).astype(np.float32)
    frame2 = frame1.copy()
    person = cv2.GaussianBlur(rng.normal(150, 40, (40, 16)), (0, 0), 2).astype(np.float32)
    frame1[30:70, 40:56] = person
    frame2[33:73, 47:63] = person  # moved by (7, 3)
    cfg = RoiMatchConfig()
    f, g, _w0 = roi_chips(frame1, (40, 30, 16, 40), frame2, (46, 33, 17, 40), cfg)
    assert max(f.shape) == cfg.chip_px and g.shape == (
        f.shape[0] + 2 * cfg.pad_px,
        f.shape[1] + 2 * cfg.pad_px,
    )
    assert match_boxes(frame1, (40, 30, 16, 40), frame2, (46, 33, 17, 40), cfg).correlation > 0.95
    other = match_boxes(frame1, (40, 30, 16, 40), frame2, (110, 60, 16, 40), cfg).correlation
    assert not other > 0.6  # a patch of background does not look like the person
    c = chip(frame1, (48.0, 50.0), (16, 40), 1.0)  # scale 1: the box itself
    np.testing.assert_allclose(c, frame1[30:70, 40:56], atol=1e-3)
