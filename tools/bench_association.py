"""Speed of the detection-driven tracker's parts: detection on 640x480, one frame of
N tracks x M detections (gating, ROI matching of the gated pairs, assignment).

Usage: python tools/bench_association.py [--tracks 50] [--detections 60] [--repeats 20]

A 640x480 IR-like frame holds M warm textured blobs on a textured background; N of them
are tracked (templates from the previous frame, where every blob was 1-3 px away;
predictions within 2 px). Prints the median milliseconds of: detection, the N x M pair
costs (state gating + ECC on the gated pairs, and how many pairs were gated), and the
Hungarian assignment on the padded (N+M)^2 matrix; then the CHNN on 10 targets x 30
measurements (random scenes) and how often it reaches the Hungarian optimum. One thread
(cv2.setNumThreads(1)).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")


def main() -> None:
    import cv2
    import numpy as np

    from pipeline.config import PipelineConfig
    from pipeline.stages import kalman
    from pipeline.stages.association import hungarian
    from pipeline.stages.detection import detect
    from pipeline.trackers.detect import DetTrack, _kcfg, pair_costs
    from pipeline.types import TargetStatus

    ap = argparse.ArgumentParser()
    ap.add_argument("--tracks", type=int, default=50)
    ap.add_argument("--detections", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    rng = np.random.default_rng(0)
    H, W = 480, 640
    cols = 10
    pos = [
        (32 + 64 * (k % cols) + rng.uniform(-4, 4), 40 + 80 * (k // cols) + rng.uniform(-4, 4))
        for k in range(a.detections)
    ]

    def frame(offset: float) -> np.ndarray:
        img = cv2.GaussianBlur(rng.normal(90, 20, (H, W)), (0, 0), 5)
        for k, (x, y) in enumerate(pos):
            tex = cv2.GaussianBlur(np.random.default_rng(k).normal(70, 25, (44, 18)), (0, 0), 2)
            x0, y0 = int(x + offset * ((k % 3) - 1)), int(y + offset)
            img[y0 - 22 : y0 + 22, x0 - 9 : x0 + 9] += tex
        return np.clip(img, 0, 255).astype(np.uint8)

    prev, cur = frame(0.0), frame(2.0)
    cfg = PipelineConfig()
    kcfg = _kcfg(cfg)
    F, Q = kalman.motion_model(kcfg)

    def timed(fn):
        ts = []
        out = None
        for _ in range(a.repeats):
            t0 = time.perf_counter()
            out = fn()
            ts.append(time.perf_counter() - t0)
        return 1e3 * float(np.median(ts)), out

    t_det, dets = timed(lambda: detect(cur, cfg.detection))
    regions = list(dets.regions)
    prev_regions = list(detect(prev, cfg.detection).regions)
    tracks, priors = [], []
    for k, r in enumerate(prev_regions[: a.tracks]):
        kf = kalman.init_state(r.box, kcfg)
        tracks.append(DetTrack(k + 1, kf, r.box, TargetStatus.TRACKING, 1, 5, 0, prev, r.box))
        priors.append(kalman.predict(kf, F, Q))
    timing: dict[str, float] = {}
    t_pairs, (cost, _lam, _gam) = timed(
        lambda: pair_costs(tracks, priors, regions, cur, cfg, timing)
    )
    gated = int(np.isfinite(cost).sum())
    miss = np.full(len(tracks), 2.3)
    new = np.full(len(regions), 9.2)
    hung = hungarian
    t_hung, res = timed(lambda: hung(np.where(np.isfinite(cost), cost, 1e9), miss, new))
    print(
        f"640x480 frame, {len(tracks)} tracks x {len(regions)} detections (of {a.detections} "
        "planted)"
    )
    print(f"detection: {t_det:.2f} ms per frame")
    print(
        f"pair costs: {t_pairs:.2f} ms ({gated} gated pairs matched by ECC, "
        f"{1e3 * timing.get('roi_match', 0) / a.repeats / max(gated, 1):.2f} ms per ECC match)"
    )
    print(
        f"assignment (Hungarian, {len(tracks) + len(regions)}^2 padded): {t_hung:.3f} ms; "
        f"{len(res.pairs)} pairs"
    )
    print(f"frame total (detection + pairs + assignment): {t_det + t_pairs + t_hung:.2f} ms")

    # CHNN on 10 targets x 30 measurements (random scene, gated Mahalanobis distances, image term)
    from pipeline.stages.chnn import chnn, cost_matrix, hungarian_reference

    trials = []
    for k in range(200):
        r = np.random.default_rng(k)
        targets = r.uniform(0, 100, (10, 2))
        meas = np.vstack([targets + r.normal(0, 1.0, (10, 2)), r.uniform(0, 100, (20, 2))])
        dist = np.linalg.norm(targets[:, None, :] - meas[None, :, :], axis=2) / 1.4
        d = cost_matrix(dist, 3.03)
        F = r.uniform(0, 0.2, d.shape) * (d < 1e9)
        trials.append((d, F))
    ts, gaps, sweeps = [], [], []
    for d, F in trials:
        t0 = time.perf_counter()
        res = chnn(d, A=1.0, B=4.03, F=F, image_weight=1.0)
        ts.append(time.perf_counter() - t0)
        _rows, best = hungarian_reference(d, F, 1.0, 1.0)
        mine = float((d + F)[res.rows, np.arange(10)].sum())
        gaps.append(mine - best)
        sweeps.append(res.sweeps)
    print(
        f"CHNN 10 targets x 30 measurements: {1e3 * float(np.median(ts)):.3f} ms per frame "
        f"(median of {len(ts)}), "
        f"{np.mean(sweeps):.1f} sweeps; equal to the Hungarian optimum in "
        f"{np.mean(np.array(gaps) < 1e-9) * 100:.0f} % "
        f"of frames"
    )


if __name__ == "__main__":
    main()
