"""STDM detection: the map against a slow reference, segmentation, ROI features and
discrimination."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy import ndimage

from pipeline.stages.detection import (
    DetectionConfig,
    clean,
    detect,
    discriminate,
    frame_shift,
    quantile_background,
    regions,
    segment,
    shift_image,
    stdm,
)


def test_stdm_matches_the_slow_reference():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (40, 50), dtype=np.uint8)
    for w in (3, 7):
        ref = ndimage.generic_filter(img.astype(np.float64), np.std, size=w, mode="reflect")
        np.testing.assert_allclose(stdm(img, w), ref, atol=1e-3)
    deep = (rng.normal(8000, 3, (30, 30))).astype(
        np.uint16
    )  # 14-bit IR, tiny variance: float64 path, never negative
    ref = ndimage.generic_filter(deep.astype(np.float64), np.std, size=5, mode="reflect")
    out = stdm(deep, 5)
    assert out.dtype == np.float64 and out.min() >= 0
    np.testing.assert_allclose(out, ref, atol=1e-6)


def test_flat_frame_has_zero_deviation_and_no_detection():
    flat = np.full((60, 80), 120, np.uint8)
    assert stdm(flat, 7).max() == 0
    assert detect(flat, DetectionConfig()).regions == ()
    assert detect(flat, DetectionConfig(method="stdm")).regions == ()


def shapes() -> np.ndarray:
    m = np.zeros((200, 300), np.uint8)
    m[20:80, 20:45] = 1  # a person-like block: P ~ 166
    cv2.circle(m, (150, 50), 20, 1, -1)  # a disk: C2 ~ 1
    m[150:156, 30:180] = 1  # a long thin bar: elongated
    m[100:106, 250:256] = 1  # a speck: too small
    cv2.rectangle(
        m, (200, 120), (280, 190), 1, 2
    )  # an outline ring: its outer contour holds it all
    return m


def test_region_features_on_hand_built_shapes():
    regs = {(int(r.box.x), int(r.box.y)): r for r in regions(shapes())}
    block = regs[(20, 20)]
    assert block.area_px == 60 * 25 and block.box.as_tuple() == (20.0, 20.0, 25.0, 60.0)
    assert block.perimeter_px == pytest.approx(
        2 * (59 + 24), abs=0.5
    )  # the polygon through pixel centres
    assert block.aspect == pytest.approx(59 / 24, rel=0.05)
    assert block.centroid == pytest.approx((32.5, 50.0), abs=0.01)
    disk = regs[(130, 30)]
    assert disk.c2 == pytest.approx(1.0, abs=0.15) and disk.c1 == pytest.approx(
        disk.perimeter_px / disk.area_px
    )
    assert regs[(30, 150)].aspect > 20


def test_discrimination_keeps_compact_targets_and_says_why_others_go():
    cfg = DetectionConfig(perimeter_px=(60.0, 400.0), max_aspect=5.0, max_complexity=3.0)
    ok, bad = discriminate(regions(shapes()), cfg)
    kept = sorted((int(r.box.x), int(r.box.y)) for r in ok)
    assert kept == [(20, 20), (130, 30), (199, 119)]
    ring = next(r for r in ok if int(r.box.x) == 199)
    assert (
        abs(ring.area_px - 83 * 73) <= 8
    )  # the outer contour's inside (cv2.rectangle rounds the corners)
    reasons = {(int(r.box.x), int(r.box.y)): r.reason for r in bad}
    assert reasons == {(30, 150): "elongated", (250, 100): "too-small"}
    ok, bad = discriminate(regions(shapes()), DetectionConfig(perimeter_px=(60.0, 250.0)))
    assert {(int(r.box.x), int(r.box.y)): r.reason for r in bad}[(199, 119)] == "too-large"


def test_clean_fills_a_closed_ring_and_drops_specks():
    cfg = DetectionConfig(min_area_px=60)
    m = clean(shapes(), cfg)
    assert m[150, 240] == 1  # inside the outline ring: filled
    assert m[103, 253] == 0  # the 36 px speck: dropped


def test_detects_warm_targets_on_a_textured_background():
    rng = np.random.default_rng(1)
    bg = cv2.GaussianBlur(rng.normal(90, 25, (240, 320)), (0, 0), 6) + rng.normal(0, 2, (240, 320))
    img = bg.copy()
    truths = [(40, 90, 22, 56), (200, 60, 26, 60)]
    for x, y, w, h in truths:
        img[y : y + h, x : x + w] += 70
    img = cv2.GaussianBlur(np.clip(img, 0, 255), (0, 0), 1.0).astype(np.uint8)
    for method in ("stdm", "foreground"):
        cfg = DetectionConfig(method=method, perimeter_px=(90.0, 600.0))
        d = detect(img, cfg)
        assert len(d.regions) == 2, method
        for (x, y, w, h), r in zip(truths, sorted(d.regions, key=lambda r: r.box.x), strict=True):
            assert r.centroid == pytest.approx((x + w / 2, y + h / 2), abs=2.0)
            assert abs(r.box.w - w) <= 6 and abs(r.box.h - h) <= 6
    assert (
        segment(detect(img, DetectionConfig(method="stdm")).std_map, DetectionConfig()).sum() > 0
    )


def road_scene(rng: np.random.Generator, person_x: float) -> np.ndarray:
    """A grey IR ground with a warmer road band (rows 100-140) and a cold building block: edges of
    the scene's own; a warm person (22 x 56 px, +45 grey levels) standing on the band's upper edge
    at ``person_x``."""
    img = cv2.GaussianBlur(rng.normal(90, 10, (240, 320)), (0, 0), 4) + rng.normal(
        0, 2, (240, 320)
    )
    img[100:140] += 25
    img[0:50, 60:200] -= 40
    x, y = int(person_x), 70
    img[y : y + 56, x : x + 22] += 45
    return np.clip(cv2.GaussianBlur(img, (0, 0), 1.0), 0, 255).astype(np.uint8)


def test_a_person_on_the_edge_of_a_road_band_is_one_region_and_the_band_is_none():
    """The STDM of the seed joins the person to the band's edges (a too-large or elongated region,
    dropped); the foreground against the background keeps the person and not the scene's own edges.
    """
    rng = np.random.default_rng(3)
    frames = [road_scene(rng, 60 + 2 * k) for k in range(30)]
    stdm_found = detect(frames[-1], DetectionConfig(method="stdm"))
    assert not any(
        abs(r.centroid[0] - 129) < 6 and abs(r.centroid[1] - 98) < 6 for r in stdm_found.regions
    )
    bg = None
    for f in frames:
        d = detect(f, DetectionConfig(), bg)
        bg = d.background
    assert len(d.regions) == 1, [(r.box, r.reason) for r in (*d.regions, *d.rejected)]
    r = d.regions[0]
    assert r.centroid == pytest.approx((60 + 2 * 29 + 11, 70 + 28), abs=2.0)
    assert abs(r.box.w - 22) <= 4 and abs(r.box.h - 56) <= 4


def test_a_still_camera_background_absorbs_static_structure_and_not_a_moving_target():
    rng = np.random.default_rng(4)
    static = cv2.GaussianBlur(rng.normal(90, 10, (120, 160)), (0, 0), 4)
    static[30:60, 20:40] += 40  # a warm parked object, there from the first frame
    bg = None
    for k in range(80):
        img = static + rng.normal(0, 2, static.shape)
        img[60:90, 60 + k // 2 : 75 + k // 2] += 40  # a person walking slowly
        d = detect(
            np.clip(img, 0, 255).astype(np.uint8), DetectionConfig(perimeter_px=(30.0, 400.0)), bg
        )
        bg = d.background
    centres = [r.centroid for r in d.regions]
    assert len(centres) == 1 and centres[0][0] == pytest.approx(60 + 79 // 2 + 7.5, abs=2.0)
    assert bg.frames == 80 and abs(float(bg.estimate[45, 30]) - float(static[45, 30])) < 8


def textured(rng: np.random.Generator, shape=(240, 320)) -> np.ndarray:
    return (cv2.GaussianBlur(rng.normal(90, 25, shape), (0, 0), 2) + 0).astype(np.float32)


@pytest.mark.parametrize("dx,dy", [(1.6, -2.3), (-3.0, 0.4), (0.0, 0.0), (3.0, 4.0), (-0.5, 0.75)])
def test_frame_shift_recovers_a_planted_translation(dx, dy):
    rng = np.random.default_rng(5)
    ref = textured(rng)
    img = shift_image(ref, dx, dy) + rng.normal(0, 2, ref.shape).astype(np.float32)
    got = frame_shift(ref, img, 4.0)
    assert got == pytest.approx((dx, dy), abs=0.35)


def test_frame_shift_is_not_pulled_by_a_large_moving_object():
    """A car-sized warm block moved 40 px is not the camera's motion: the search stays within
    ``max_px``."""
    rng = np.random.default_rng(6)
    ref = textured(rng)
    ref[120:200, 20:140] += 80
    img = shift_image(ref, 1.0, 1.0).copy()
    img[121:201, 21:141] -= 80  # the block, moved with the camera, then 40 px further
    img[121:201, 61:181] += 80
    assert frame_shift(ref, img, 4.0) == pytest.approx((1.0, 1.0), abs=0.35)
    assert (
        cv2.phaseCorrelate(ref.astype(np.float64), img.astype(np.float64))[0][0] > 30
    )  # the global peak is the block


def walking_frames(rng: np.random.Generator, n: int, shake: bool, contrast: float = 45.0):
    """A textured IR ground with a warm person (22 x 56, +``contrast``) walking 2 px a frame from x
    = 20 and another standing at x = 250 (rows 20-76) for the first 60 % of the frames, then
    walking left; camera shake up to 2 px."""
    ground = textured(rng)
    frames, boxes = [], []
    for k in range(n):
        img = ground.copy()
        x = 20 + 2 * k
        img[100:156, x : x + 22] += contrast
        sx = 250 if k < 0.6 * n else 250 - 3 * (k - int(0.6 * n))
        img[20:76, sx : sx + 22] += contrast
        jx, jy = (rng.uniform(-2, 2), rng.uniform(-2, 2)) if shake else (0.0, 0.0)
        img = shift_image(img, jx, jy) + rng.normal(0, 2, img.shape).astype(np.float32)
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
        boxes.append([(x + jx, 100 + jy), (sx + jx, 20 + jy)])
    return ground, frames, boxes


def test_quantile_background_leaves_out_walking_and_lingering_targets_and_the_shake():
    rng = np.random.default_rng(7)
    ground, frames, _ = walking_frames(rng, 100, shake=True)
    idx = np.linspace(0, 99, 25).round().astype(int)
    cfg = DetectionConfig()
    bg = quantile_background([frames[i] for i in idx], cfg)
    assert bg.static and bg.frames == 25
    dx, dy = frame_shift(
        ground, frames[0].astype(np.float32), 4.0
    )  # the estimate lies in the first sample's frame
    err = np.abs(bg.estimate - shift_image(ground, dx, dy))[10:-10, 10:-10]
    assert np.median(err) < 2.0 and np.percentile(err, 99) < 8.0  # neither person left in it (+45)
    median = quantile_background(
        [frames[i] for i in idx], DetectionConfig(background_quantile=0.5)
    )
    assert (
        float(median.estimate[45, 260] - bg.estimate[45, 260]) > 30
    )  # the median keeps the one standing for 60 %


def test_a_sequence_background_registered_to_a_shaken_frame_finds_its_targets():
    """A person standing from the first frame for 60 % of the sequence and one walking from it: the
    sequence's background, registered to every shaken frame, gives both and nothing else."""
    rng = np.random.default_rng(8)
    _, frames, boxes = walking_frames(rng, 100, shake=True)
    cfg = DetectionConfig(perimeter_px=(60.0, 600.0))
    bg = quantile_background([frames[i] for i in np.linspace(0, 99, 25).round().astype(int)], cfg)
    for k in (*range(0, 100, 3), 40, 55):
        d = detect(frames[k], cfg, bg)
        assert d.background is bg  # a static background is not updated
        assert len(d.regions) == 2, (k, [(r.box, r.reason) for r in (*d.regions, *d.rejected)])
        for r, (x, y) in zip(
            sorted(d.regions, key=lambda r: -r.centroid[1]), boxes[k], strict=True
        ):
            assert r.centroid == pytest.approx((x + 11, y + 28), abs=2.5)
    # a fainter pair (+15 grey levels): the shake left in the difference raises the threshold above
    # them
    _, faint, fboxes = walking_frames(np.random.default_rng(8), 100, shake=True, contrast=15.0)
    fbg = quantile_background([faint[i] for i in np.linspace(0, 99, 25).round().astype(int)], cfg)
    # the registration alone: growing the regions (grow_k) fills more of them either way
    cfg = DetectionConfig(perimeter_px=(60.0, 600.0), grow_k=0.0)
    unregistered = DetectionConfig(perimeter_px=(60.0, 600.0), max_shift_px=0.0, grow_k=0.0)

    def covered(c: DetectionConfig) -> float:  # share of the people's pixels that are foreground
        got = want = 0
        for k in range(0, 100, 3):
            m = detect(faint[k], c, fbg).mask
            for x, y in fboxes[k]:
                x, y = round(x), round(y)
                got += int(m[y + 4 : y + 52, x + 3 : x + 19].sum())
                want += 48 * 16
        return got / want

    assert sum(len(detect(faint[k], cfg, fbg).regions) for k in range(0, 100, 3)) == 2 * 34
    assert covered(cfg) > 0.9 and covered(unregistered) < 0.8 * covered(cfg), (
        covered(cfg),
        covered(unregistered),
    )


def test_touching_bodies_are_split_and_one_body_is_not():
    """Two bodies joined by a hand give two regions at their own centres; one body with head and
    legs stays one region (its head and legs are too thin to make a second core)."""
    from pipeline.stages.detection import split_touching

    def outer(mask):
        cs, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        return list(cs)

    def person(m, cx):
        cv2.ellipse(m, (cx, 50), (11, 20), 0, 0, 360, 1, -1)  # torso
        cv2.circle(m, (cx, 24), 6, 1, -1)  # head
        cv2.rectangle(m, (cx - 8, 66), (cx - 4, 95), 1, -1)  # legs
        cv2.rectangle(m, (cx + 4, 66), (cx + 8, 95), 1, -1)

    one = np.zeros((110, 120), np.uint8)
    person(one, 40)
    assert len(split_touching(outer(one), 0.7, 10)) == 1
    two = np.zeros((110, 120), np.uint8)
    person(two, 40)
    person(two, 66)
    cv2.rectangle(two, (50, 48), (56, 51), 1, -1)  # a hand on the other's arm
    assert len(outer(two)) == 1
    parts = split_touching(outer(two), 0.7, 10)
    centres = sorted(cv2.boundingRect(c)[0] + cv2.boundingRect(c)[2] / 2 for c in parts)
    assert len(parts) == 2 and abs(centres[0] - 40.5) <= 3 and abs(centres[1] - 66.5) <= 3
    assert len(split_touching(outer(two), 0.0, 10)) == 1  # 0 disables


def test_a_distant_person_is_kept_and_noise_specks_are_not():
    """A warm 5 x 12 px person (boundary about 30 px) on a noisy IR ground against the sequence's
    background: kept by the default boundary range (from 24 px), dropped as too small under the
    range's former floor of 40; the noise makes no region either way."""
    rng = np.random.default_rng(11)
    ground = cv2.GaussianBlur(rng.normal(90, 10, (120, 160)), (0, 0), 4)
    frames = []
    for k in range(25):
        img = ground + rng.normal(0, 2, ground.shape)
        img[50:62, 20 + 4 * k : 25 + 4 * k] += 40
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
    bg = quantile_background(frames, DetectionConfig())
    d = detect(frames[12], DetectionConfig(), bg)
    assert len(d.regions) == 1, [(r.box, r.reason) for r in (*d.regions, *d.rejected)]
    assert d.regions[0].centroid == pytest.approx((20 + 48 + 2.5, 56), abs=1.5)
    old = detect(frames[12], DetectionConfig(perimeter_px=(40.0, 900.0), min_area_px=40), bg)
    assert not old.regions and [r.reason for r in old.rejected] == ["too-small"]


def cold_person_frames(
    n: int = 25, light_at: int | None = 12
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(IR, visible BGR) frames: a 10 x 24 px person in a red coat walking right 5 px a frame from
    x = 10 on grey ground, only 4 grey levels warmer than the ground in the IR (under the IR
    foreground's threshold); on frame ``light_at`` (0-based) a patch of the visible ground
    brightens with no IR change."""
    rng = np.random.default_rng(4)
    ground_ir = cv2.GaussianBlur(rng.normal(90, 8, (120, 160)), (0, 0), 3)
    ground_vis = np.full((120, 160, 3), 128.0) + rng.normal(0, 3, (120, 160, 3))
    irs, viss = [], []
    for k in range(n):
        ir = ground_ir + rng.normal(0, 1.5, ground_ir.shape)
        vis = ground_vis + rng.normal(0, 2, ground_vis.shape)
        x = 10 + 5 * k
        ir[50:74, x : x + 10] += 4
        vis[50:74, x : x + 10] = (40, 40, 200)  # BGR red
        if k == light_at:
            vis[10:30, 120:150] += 60
        irs.append(np.clip(ir, 0, 255).astype(np.uint8))
        viss.append(np.clip(vis, 0, 255).astype(np.uint8))
    return irs, viss


def test_a_target_at_the_ground_s_temperature_is_found_in_visible_with_weak_ir_support():
    """The person of :func:`cold_person_frames` is a region with reason ``visible``; the patch of
    light, with no IR support, is none; with ``visible_support_k`` 0 neither is."""
    from pipeline.stages.detection import RegionReason

    irs, viss = cold_person_frames()
    labs = [cv2.cvtColor(v, cv2.COLOR_BGR2LAB).astype(np.float32) for v in viss]
    cfg = DetectionConfig()
    bg = quantile_background(irs, cfg, labs)
    d = detect(irs[12], cfg, bg, viss[12])
    assert [r.reason for r in d.regions] == [RegionReason.VISIBLE], [
        (r.box, r.reason) for r in d.regions
    ]
    assert d.regions[0].centroid == pytest.approx((10 + 60 + 5, 62), abs=2.0)
    assert abs(d.regions[0].box.h - 24) <= 4
    assert not detect(irs[12], DetectionConfig(visible_support_k=0), bg, viss[12]).regions


@pytest.mark.parametrize("excess", [20.0, 30.0, 50.0])
def test_a_region_scores_its_contrast_over_the_background(excess):
    """A block ``excess`` grey levels warmer than a flat background with noise 4: contrast
    ``excess`` over the frame's robust deviation from the background (4.45 for the rounded
    noise), score ``1 - exp(-contrast / foreground_k)``."""
    rng = np.random.default_rng(8)
    bg = np.full((120, 160), 90.0, np.float32)
    frame = bg + rng.normal(0, 4, bg.shape).astype(np.float32)
    frame[40:90, 60:80] += excess
    from pipeline.stages.detection import Background

    d = detect(
        np.clip(frame, 0, 255).astype(np.uint8),
        DetectionConfig(max_shift_px=0),
        Background(bg, 25, static=True),
    )
    (r,) = d.regions
    sigma = 1.4826 * np.median(np.abs(np.clip(frame, 0, 255).astype(np.uint8) - bg))
    assert 4.2 < sigma < 4.7 and r.contrast == pytest.approx(excess / sigma, rel=0.05)
    assert r.score == pytest.approx(1 - np.exp(-r.contrast / 4.0), abs=1e-9)
    stdm_only = detect(np.clip(frame, 0, 255).astype(np.uint8), DetectionConfig(method="stdm"))
    assert all(
        np.isnan(q.contrast) and q.score == min(1.0, 1 / max(q.c2, 1)) for q in stdm_only.regions
    )


@pytest.mark.parametrize("seeds", [3, 40, 300])
def test_the_weak_components_filled_from_the_cores_are_the_labelled_ones(seeds):
    """:func:`grow`'s flood fill from each core finds the same 8-connected components, pixel for
    pixel and box for box, as labelling the whole frame; past 255 components it labels."""
    from pipeline.stages._labels import components
    from pipeline.stages.detection import _weak_components

    rng = np.random.default_rng(seeds)
    for _ in range(20):
        mask = (rng.random((90, 130)) < 0.45).astype(np.uint8)
        ys, xs = np.nonzero(mask)
        pick = rng.choice(len(ys), size=min(seeds, len(ys)), replace=False)
        pts = [(int(xs[i]), int(ys[i])) for i in pick]
        n, lab, boxes, owner = _weak_components(mask, pts)
        _, comp, stats, _ = components(mask)
        assert len(set(owner.tolist())) == n - 1 or seeds > 255
        for (x, y), o in zip(pts, owner, strict=True):
            c = comp[y, x]
            np.testing.assert_array_equal(lab == o, comp == c)
            assert boxes[o] == tuple(int(v) for v in stats[c, :4])


@pytest.mark.parametrize("grow_k,rows", [(1.5, (40, 100)), (0.0, (40, 70))])
def test_a_walker_with_cold_legs_gets_a_whole_body_box(grow_k, rows):
    """A torso 30 grey levels warmer than the ground and legs only 9 warmer (under the
    foreground threshold of 4 deviations, 11.9 here): grown, the box spans torso and legs."""
    from pipeline.stages.detection import Background

    rng = np.random.default_rng(9)
    bg = np.full((140, 160), 90.0, np.float32)
    frame = bg + rng.normal(0, 2, bg.shape).astype(np.float32)
    frame[40:70, 70:90] += 30  # torso (and head)
    frame[70:100, 72:88] += 9  # legs
    cfg = DetectionConfig(max_shift_px=0, grow_k=grow_k)
    d = detect(np.clip(frame, 0, 255).astype(np.uint8), cfg, Background(bg, 25, static=True))
    (r,) = d.regions
    assert r.box.y == pytest.approx(rows[0], abs=1.5)
    assert r.box.y2 == pytest.approx(rows[1], abs=1.5)


def test_the_cross_power_spectrum_does_not_depend_on_where_it_lies_in_memory():
    """The registration's normalised cross-power spectrum is the same bit for bit whatever the
    alignment of the spectrum in memory (``cv2.magnitude``, used before, rounded differently with
    it: the same sequence gave different backgrounds and detections from run to run)."""
    from pipeline.stages.detection import _unit

    rng = np.random.default_rng(7)
    a, b = textured(rng, (120, 160)), textured(rng, (120, 160))
    fa = cv2.dft(a - float(a.mean()), flags=cv2.DFT_COMPLEX_OUTPUT)
    fb = cv2.dft(b - float(b.mean()), flags=cv2.DFT_COMPLEX_OUTPUT)
    cross = cv2.mulSpectrums(fb, fa, 0, conjB=True)

    def placed(x: np.ndarray, offset: int) -> np.ndarray:
        buf = np.empty(x.nbytes + 128, np.uint8)
        start = (-buf.ctypes.data) % 64 + offset
        y = buf[start : start + x.nbytes].view(np.float32).reshape(x.shape)
        y[...] = x
        return y

    junk = []  # other allocations between calls move where the temporaries land
    results = set()
    for o in range(0, 64, 4):
        junk.append(np.empty(1 + 37 * o, np.uint8))
        results.add(_unit(placed(cross, o)).tobytes())
    assert len(results) == 1
    # element by element in float32, as numpy computes it (cv2.magnitude differs from this on a
    # third of the elements, by the alignment of its arrays)
    re, im = cross[..., 0], cross[..., 1]
    expected = cross / np.maximum(np.sqrt(re * re + im * im), np.float32(1e-9))[..., None]
    assert _unit(cross.copy()).tobytes() == expected.astype(np.float32).tobytes()
    np.testing.assert_allclose(np.hypot(*np.moveaxis(_unit(cross), -1, 0)), 1.0, rtol=1e-5)


@pytest.mark.parametrize("shape", [(9, 11), (10, 12), (1, 2)])
def test_the_counted_residual_test_agrees_with_the_median(shape):
    """``_residual_below`` (counting the differences under the bound) answers exactly as the
    median compared with the bound, at bounds on either side of it, on it, and between an even
    count's two middle values."""
    from pipeline.stages.detection import _residual, _residual_below, _shared

    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.integers(0, 8, shape).astype(np.float32) / 4  # ties, as area-averaged greys
        b = rng.integers(0, 8, shape).astype(np.float32) / 4
        for dx, dy in ((0, 0), (1, 0), (-2, 1), (0, 40)):
            med = _residual(a, b, dx, dy)
            d = np.sort(_shared(a, b, dx, dy).ravel())
            bounds = {med, float(np.nextafter(med, np.inf)), med - 0.25, med + 0.25}
            if d.size % 2 == 0 and d.size:
                bounds.add(float(0.5 * (d[d.size // 2 - 1] + d[d.size // 2])) + 1e-3)
            for bound in bounds:
                assert _residual_below(a, b, dx, dy, bound) == (med < bound), (dx, dy, bound)
    assert _residual_below(a, b, 0, 40, float("inf")) is False  # no shared pixels


def test_the_median_equals_numpy_s_bit_for_bit():
    """``median`` (one-index partition) returns ``np.median``'s value to the last bit on odd and
    even counts, ties, float32, float64 and integers, and NaN on an empty array."""
    from pipeline.stages.detection import median

    rng = np.random.default_rng(11)
    for t in range(600):
        n = int(rng.integers(1, 80))
        dtype = (np.float32, np.float64, np.uint8)[t % 3]
        a = rng.normal(0, 10 ** float(rng.uniform(-6, 6)), n)
        if t % 4 == 0:
            a = np.round(a * 4) / 4  # ties
        a = np.abs(a).astype(dtype) if dtype is np.uint8 else a.astype(dtype)
        got, want = median(a.reshape(1, -1) if t % 5 == 0 else a), float(np.median(a))
        assert got == want, (dtype, n, got, want)
    assert np.isnan(median(np.zeros(0, np.float32)))


def test_the_per_pixel_order_statistic_equals_numpy_s_partition():
    """``kth_smallest`` (the background's per-pixel quantile) gives ``np.partition``'s k-th value
    of every pixel exactly: ties, both float types, every k of small stacks, blocks of columns
    that do not divide the frame; an order outside the stack is refused."""
    from pipeline.stages.detection import kth_smallest

    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 7, 25):
        for dtype in (np.float32, np.float64):
            ties = rng.integers(0, 5, (n, 23, 37)).astype(dtype)
            spread = rng.normal(0, 50, (n, 31, 29)).astype(dtype)
            for k in range(n):
                for a in (ties, spread):
                    want = np.partition(a, k, axis=0)[k]
                    got = kth_smallest(a, k)
                    assert got.dtype == a.dtype and np.array_equal(got, want), (n, k, dtype)
    with pytest.raises(ValueError):
        kth_smallest(np.zeros((3, 4, 4), np.float32), 3)
    with pytest.raises(ValueError):
        kth_smallest(np.zeros((3, 4, 4), np.uint8), 1)


def test_the_visible_foreground_s_compiled_differences_equal_numpy_s():
    """The visible foreground's differences and mask, compiled, equal numpy's element-wise
    formulas bit for bit (float32, thresholds given as Python floats compare in float32)."""
    from pipeline.stages.detection import _either_above, _visible_differences

    rng = np.random.default_rng(5)
    for _ in range(10):
        lab = (rng.random((37, 53, 3)) * [100, 255, 255] - [0, 128, 128]).astype(np.float32)
        bg = (lab + rng.normal(0, 5, lab.shape)).astype(np.float32)
        gain = float(np.float32(rng.uniform(0.8, 1.2)))
        dL, dc = _visible_differences(lab, bg, np.float32(gain))
        want_dL = lab[..., 0] - gain * bg[..., 0]
        want_dc = np.sqrt((lab[..., 1] - bg[..., 1]) ** 2 + (lab[..., 2] - bg[..., 2]) ** 2)
        assert dL.tobytes() == want_dL.tobytes() and dc.tobytes() == want_dc.tobytes()
        ta, tb = float(rng.uniform(1, 8)), float(rng.uniform(1, 8))  # not float32 values
        want = ((want_dc > ta) | (want_dL > tb)).astype(np.uint8)
        np.testing.assert_array_equal(_either_above(dc, np.float32(ta), dL, np.float32(tb)), want)
