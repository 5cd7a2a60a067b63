"""DRLSE: planted shapes recovered, the fast kernel equals the numpy reference, configs
validated."""

import cv2
import numpy as np
import pytest

from pipeline.stages import levelset as L


def _blob(h=100, w=80, cx=40.0, cy=50.0, a=14.0, b=28.0, contrast=50.0, noise=2.5, seed=0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    truth = ((xx - cx) / a) ** 2 + ((yy - cy) / b) ** 2 < 1
    img = (
        95
        + contrast * cv2.GaussianBlur(truth.astype(np.float32), (0, 0), 1.2)
        + rng.normal(0, noise, (h, w))
    )
    return np.clip(img, 0, 255).astype(np.uint8), truth


def _iou(a, b):
    return (a & b).sum() / (a | b).sum()


def _kernel(phi, em, cfg, n, alpha=None, stop=(0, 0, 0.0), n_refine=0):
    """``_band_iterations`` on ``phi`` in place with ``cfg``'s weights; ``stop`` = (check_every,
    checks back, tolerance), 0 for none. Returns its (main iterations, checks, refined)."""
    f32 = np.float32
    dps, de = L._polynomials(float(cfg.dirac_width))
    return L._band_iterations(
        phi,
        em.g,
        em.gx,
        em.gy,
        n,
        f32(cfg.distance_weight),
        f32(cfg.length_weight),
        f32(cfg.area_weight if alpha is None else alpha),
        f32(cfg.dirac_width),
        f32(cfg.timestep),
        f32(cfg.band_px),
        dps,
        de,
        *stop,
        np.zeros(n // 5 + 4, np.int64),
        n_refine,
    )


@pytest.mark.parametrize("a, b", [(14, 14), (14, 28), (22, 12)])
def test_planted_disk_and_ellipses_recovered(a, b):
    img, truth = _blob(a=a, b=b)
    cfg = L.LevelSetConfig()
    phi0 = L.box_step(
        img.shape, (40 - a * 1.35, 50 - b * 1.35, 2 * a * 1.35, 2 * b * 1.35), cfg.step_height
    )
    res = L.evolve(phi0, L.edge_map(img, cfg), cfg)
    assert res.converged
    assert _iou(res.phi < 0, truth) >= 0.9


def test_warm_start_follows_a_moved_target():
    img, _truth = _blob()
    cfg = L.LevelSetConfig()
    first = L.evolve(L.box_step(img.shape, (21, 12, 38, 76), 2.0), L.edge_map(img, cfg), cfg)
    img2, truth2 = _blob(cx=43.0, cy=48.0, seed=1)
    moved = cv2.warpAffine(
        first.phi, np.float32([[1, 0, 3], [0, 1, -2]]), (80, 100), borderMode=cv2.BORDER_REPLICATE
    )
    res = L.evolve(moved, L.edge_map(img2, cfg), cfg, warm=True)
    assert res.iterations <= cfg.max_iterations_warm + cfg.refine_iterations
    assert _iou(res.phi < 0, truth2) >= 0.9


def test_compiled_differences_equal_opencv_sobel():
    rng = np.random.default_rng(3)
    for h, w in ((1, 1), (1, 7), (9, 1), (2, 3), (31, 17)):
        a = rng.normal(0, 40, (h, w)).astype(np.float32)
        dx, dy = L._central_diff_fast(a)
        for got, (ox, oy) in ((dx, (1, 0)), (dy, (0, 1))):
            ref = cv2.Sobel(
                a, cv2.CV_32F, ox, oy, ksize=1, scale=0.5, borderType=cv2.BORDER_REPLICATE
            )
            np.testing.assert_array_equal(got, ref)
    assert L._central_diff_fast(np.array([[0, 2, 6]], np.float32))[0].tolist() == [[1.0, 3.0, 2.0]]


def test_fast_kernel_equals_reference_step():
    img, truth = _blob()
    cfg = L.LevelSetConfig()
    em = L.edge_map(img, cfg)
    d_out = cv2.distanceTransform((~truth).astype(np.uint8), cv2.DIST_L2, 5)
    d_in = cv2.distanceTransform(truth.astype(np.uint8), cv2.DIST_L2, 5)
    phi = (np.clip(d_out - d_in, -1.5, 1.5) * 0.5).astype(
        np.float32
    )  # every pixel inside the band
    ref = L.evolve_reference(phi, em, cfg, 1)
    fast = phi.copy()
    _kernel(fast, em, cfg, 1)
    np.testing.assert_allclose(fast[1:-1, 1:-1], ref[1:-1, 1:-1], atol=1e-5)


@pytest.mark.parametrize("eps", [0.5, 1.5, 3.0])
def test_polynomials_give_dp_and_the_dirac_within_float32_rounding(eps):
    # the kernel's d_p(s) = sinc(2 s) on s < 1 and delta_eps(p) on |p| <= eps, evaluated as it
    # does (float32 Horner in x = 2 t - 1), against the formulas in float64
    dps, de = L._polynomials(eps)
    s = np.linspace(0, 1, 20001, dtype=np.float32)
    p = np.linspace(-eps, eps, 20001).astype(np.float32)
    got_dps = np.array([L._poly.py_func(np.float32(v * v), dps) for v in s[::7]], np.float64)
    r = (p[::7] / np.float32(eps)).astype(np.float32)
    got_de = np.array([L._poly.py_func(np.float32(v * v), de) for v in r], np.float64)
    want_dps = np.sinc(2.0 * s[::7].astype(np.float64))
    want_de = (1 + np.cos(np.pi * p[::7].astype(np.float64) / eps)) / (2 * eps)
    assert np.abs(got_dps - want_dps).max() < 4e-7
    assert np.abs(got_de - want_de).max() < 4e-7 / eps
    assert got_dps[0] == pytest.approx(1.0, abs=4e-7) and got_de[len(r) // 2] == pytest.approx(
        1 / eps, abs=4e-7
    )


def _narrow_band_oracle(phi, em, cfg, iterations):
    """The narrow-band scheme written densely: every iteration recomputes the band everywhere and
    takes the reference step's values on its 3x3 dilation (the array's outer ring is the Neumann
    copy)."""
    phi = phi.astype(np.float32, copy=True)
    for _ in range(iterations):
        L._neumann(phi)
        near = np.abs(phi) < cfg.band_px
        for axis in (0, 1):
            for shift in (1, -1):
                near |= (
                    phi * np.roll(phi, shift, axis) <= 0
                )  # wrapped neighbours only reach the outer ring
        upd = cv2.dilate(near.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        upd[0, :] = upd[-1, :] = upd[:, 0] = upd[:, -1] = False
        phi = np.where(upd, L.reference_step(phi, em, cfg, cfg.area_weight), phi).astype(
            np.float32
        )
    L._neumann(phi)
    return phi


def test_band_kernel_follows_a_moving_front_like_the_dense_band_scheme():
    # a cold start far outside the target: the front crosses ~20 px, so the band leaves every pixel
    # it started on and the kernel's band bookkeeping (band test, dilations, scan box) is
    # exercised; a pixel missed there would stall part of the front
    img, _ = _blob()
    cfg = L.LevelSetConfig()
    em = L.edge_map(img, cfg)
    phi0 = L.box_step(img.shape, (14, 4, 52, 92), cfg.step_height)

    def kernel(n):
        phi = phi0.copy()
        _kernel(phi, em, cfg, n)
        return phi

    np.testing.assert_allclose(kernel(8), _narrow_band_oracle(phi0, em, cfg, 8), atol=1e-3)
    # further on, this noisy image's DRLSE amplifies float32 rounding (the kernel's polynomials and
    # approximate reciprocals against numpy's sinc and cos) in the values,
    # so compare the regions: ~3500 px changed sides, all but a few dozen alike
    got, want = kernel(80) < 0, _narrow_band_oracle(phi0, em, cfg, 80) < 0
    assert ((phi0 < 0) != want).sum() > 3000
    assert (got != want).sum() <= 100


def test_refinement_in_the_same_call_equals_a_second_call_with_alpha_zero():
    img, _ = _blob()
    cfg = L.LevelSetConfig()
    em = L.edge_map(img, cfg)
    phi0 = L.box_step(img.shape, (21, 12, 38, 76), cfg.step_height)
    rule = (5, 2, 0.002)
    one, two = phi0.copy(), phi0.copy()
    got = _kernel(one, em, cfg, 40, stop=rule, n_refine=7)
    first = _kernel(two, em, cfg, 40, stop=rule)
    assert first[2] is False and got[:2] == first[:2] and got[2] is True
    before = two.copy()
    _kernel(two, em, cfg, 7, alpha=0.0)
    assert not np.array_equal(before, two)  # the refinement moved something
    np.testing.assert_array_equal(one, two)
    # nothing inside: no refinement
    assert (
        _kernel(np.full(img.shape, np.float32(2.0)), em, cfg, 10, stop=rule, n_refine=7)[2]
        is False
    )


def test_fast_and_reference_segment_alike():
    img, _truth = _blob()
    cfg = L.LevelSetConfig(refine_iterations=0, stop_tolerance=1e-9, max_iterations_cold=100)
    em = L.edge_map(img, cfg)
    phi0 = L.box_step(img.shape, (21, 12, 38, 76), cfg.step_height)
    fast = L.evolve(phi0, em, cfg).phi
    ref = L.evolve_reference(phi0, em, cfg, 100)
    assert _iou(fast < 0, ref < 0) >= 0.98


def test_iteration_callback_sees_the_area():
    img, _ = _blob()
    cfg = L.LevelSetConfig()
    seen = []
    res = L.evolve(
        L.box_step(img.shape, (21, 12, 38, 76), 2.0),
        L.edge_map(img, cfg),
        cfg,
        iter_callback=seen.append,
    )
    its = [s.iteration for s in seen]
    assert its == list(range(cfg.check_every, cfg.check_every * (len(its) + 1), cfg.check_every))
    # every check of the run, in order: the last one is where the stopping rule held, and the
    # refinement after it moves the front by a pixel or so
    assert its[-1] <= res.iterations <= its[-1] + cfg.refine_iterations
    assert abs(seen[-1].area_px - int((res.phi < 0).sum())) <= 0.05 * seen[-1].area_px


def test_edge_indicator_low_on_edges_high_on_flat():
    img, truth = _blob(noise=0.0)
    em = L.edge_map(img, L.LevelSetConfig(edge_scale_auto=False))
    edge = cv2.morphologyEx(truth.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3))).astype(
        bool
    )
    assert (
        em.g[edge].mean() < 0.1
        and em.g[~cv2.dilate(edge.astype(np.uint8), np.ones((9, 9))).astype(bool)].min() > 0.85
    )


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(timestep=10, distance_weight=0.04), "must be < 0.25"),
        (dict(dirac_width=0), "dirac_width"),
        (dict(step_height=1.0), "step_height"),
        (dict(stop_window=2, check_every=5), "stop_window"),
        (dict(band_px=1.0), "band_px"),
    ],
)
def test_bad_config(kw, match):
    with pytest.raises(ValueError, match=match):
        L.LevelSetConfig(**kw)
