"""The connected components the stages share: OpenCV's default components, faster."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pipeline.stages._labels import components


@pytest.mark.parametrize("shape", [(1, 1), (3, 5), (47, 61), (120, 160), (480, 640)])
def test_components_equal_opencv_s_default(shape):
    """Labels, statistics and centroids equal ``cv2.connectedComponentsWithStats``' with
    8-connectivity, on noise of every density and on blobs with holes and diagonal contacts."""
    rng = np.random.default_rng(shape[0])
    masks = [(rng.random(shape) < p).astype(np.uint8) for p in (0.0, 0.05, 0.3, 0.6, 1.0)]
    blobs = np.zeros(shape, np.uint8)
    for _ in range(12):
        y, x = rng.integers(0, shape[0]), rng.integers(0, shape[1])
        cv2.circle(blobs, (int(x), int(y)), int(rng.integers(1, 2 + max(shape) // 6)), 1, -1)
    masks += [blobs, blobs & (rng.random(shape) < 0.9).astype(np.uint8)]
    for m in masks:
        want = cv2.connectedComponentsWithStats(m, connectivity=8)
        got = components(m)
        assert got[0] == want[0]
        for a, b in zip(got[1:], want[1:], strict=True):
            assert a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
