"""The fusion paper's Monte Carlo study of association purity: state only, image only, fused.

Usage: python tools/purity_study.py [--runs 50] [--out DIR] [--seed 0] [--matcher ecc|gat]

Set-up (docs/algorithms.md §5b, the paper's settings where it gives them):

* 4 targets of classes {1, 1, 2, 3} (targets 1 and 2 look alike), 100 frames 2 s apart,
  every target detected every frame (P_D = 1, no false alarms);
* position measurements with noise variance 2.25 m^2 per axis; each target follows a
  designed route plus a Singer-model manoeuvre perturbation per axis (time constant 20 s,
  acceleration sigma 0.02 m/s^2: about 5 m of drift by the crossings, so that the
  scenarios survive it), different in every run;
* the routes recreate the paper's two scenarios (:func:`routes`): look-alikes 1 and 2
  converge and then turn onto each other's routes (their paths cross), and targets 3 and 4
  of other classes run straight beside them, so that every manoeuvre of 1 and 2 away from
  a straight neighbour is ambiguous for the state;
* every detection carries an image chip: its class template (32 x 32) rotated by
  U[-20, 20] deg, brightness offset U[-10, 10], contrast U[0.9, 1.1], Gaussian noise of
  variance 100, on a 48 x 48 canvas;
* one track per target, started from its first two measurements; a constant-velocity
  Kalman filter (q = 1 m^2/s^3); association by Hungarian on the cost -ln Λ_S (state),
  -ln Λ_I (image: Λ_I = exp(-20 (1 - rho)) of the ECC correlation rho of the track's last
  chip with the detection's; ``--sharpness 0`` is the paper's max(rho, eps), with which a
  wrong class's 0.8 against the right one's 0.97 barely registers) or their sum (fused);
  a track takes the chip of the detection it was given.

Writes ``DIR/purity.json``: ``state``, ``image``, ``fused`` (4 x 4 lists, row i = true
target, column j = track, fraction of frames pooled over runs), ``none`` (per mode, per
target, the fraction of frames its detection went to no track), ``diagonal`` (per mode),
``paper`` (its reported diagonals) and the settings; ``DIR/purity.png`` (the matrices and
the routes of one run).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

DT_S = 2.0
FRAMES = 100
NOISE_VAR_M2 = 2.25
CLASSES = (1, 1, 2, 3)
PAPER = {"state": [0.479, 0.405, 0.374, 0.645], "fused": [0.889, 0.862, 0.865, 0.879]}
MODES = ("state", "image", "fused")
SIDE_BY_SIDE_M = 1.5
SINGER_TAU_S = 20.0
SINGER_SIGMA = 0.02


def routes() -> np.ndarray:
    """Designed routes (4, FRAMES, 2) in metres, before the per-run manoeuvres.

    All run 20 m/frame in +x; 2 and 4 run 3 frames (60 m) behind 1 and 3. Targets 3 (class
    2) and 4 (class 3) close in from y = +-60 m onto lanes at +-11.5 m and keep them.
    Look-alikes 1 and 2 come in from +-60 m beside them, 1.5 m away (1 beside 3, 2 beside
    4), then turn onto each other's lanes (frames 20-30 and 23-33: their paths cross, 60 m
    apart, which the state tells apart and their images cannot), run beside the other
    straight target until frames 60 and 63, and turn away to +-40 m. Each of the four
    side-by-side runs ends with one target turning off and the other going straight: there
    the state is a coin toss and the images decide.
    """
    t = np.arange(FRAMES, dtype=float)
    speed = 10.0 * DT_S  # m per frame
    lane = 10.0 + SIDE_BY_SIDE_M

    def ramp(a: float, b: float, t0: float, t1: float) -> np.ndarray:
        u = np.clip((t - t0) / (t1 - t0), 0, 1)
        return a + (b - a) * (3 * u**2 - 2 * u**3)

    out = np.zeros((4, FRAMES, 2))
    out[0, :, 0] = out[2, :, 0] = speed * t
    out[1, :, 0] = out[3, :, 0] = speed * (t - 3)
    out[2, :, 1] = ramp(60.0, lane, 0, 6)
    out[3, :, 1] = ramp(-60.0, -lane, 0, 6)
    out[0, :, 1] = ramp(60.0, 10.0, 0, 8) + ramp(0.0, -20.0, 20, 30) + ramp(0.0, 50.0, 60, 70)
    out[1, :, 1] = ramp(-60.0, -10.0, 0, 8) + ramp(0.0, 20.0, 23, 33) + ramp(0.0, -50.0, 63, 73)
    return out


def singer(
    rng: np.random.Generator, n: int, tau_s: float = SINGER_TAU_S, sigma_a: float = SINGER_SIGMA
) -> np.ndarray:
    """Position perturbation (n, 2), m, of a Singer acceleration process per axis (first-order
    Gauss-Markov acceleration, time constant ``tau_s``, std ``sigma_a`` m/s^2), from rest."""
    a = np.zeros((n, 2))
    rho = math.exp(-DT_S / tau_s)
    for k in range(1, n):
        a[k] = rho * a[k - 1] + math.sqrt(1 - rho * rho) * sigma_a * rng.standard_normal(2)
    v = np.cumsum(a, axis=0) * DT_S
    return np.cumsum(v, axis=0) * DT_S


def templates() -> dict[int, np.ndarray]:
    """Class templates, 32 x 32 grey: 1 a car from above, 2 a truck with a trailer, 3 a tank-like
    shape."""
    import cv2

    out = {}
    t = np.full((32, 32), 60.0)
    cv2.rectangle(t, (6, 9), (25, 22), 190, -1)
    cv2.rectangle(t, (11, 11), (18, 20), 120, -1)
    out[1] = t
    t = np.full((32, 32), 60.0)
    cv2.rectangle(t, (3, 11), (10, 20), 210, -1)
    cv2.rectangle(t, (12, 8), (29, 23), 160, -1)
    out[2] = t
    t = np.full((32, 32), 60.0)
    cv2.circle(t, (16, 16), 9, 180, -1)
    cv2.rectangle(t, (16, 14), (31, 18), 220, -1)
    out[3] = t
    return out


def make_chip(tpl: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One observed chip: the template rotated, with brightness, contrast and noise, on a 48 x 48
    canvas."""
    import cv2

    canvas = np.full((48, 48), 60.0)
    canvas[8:40, 8:40] = tpl
    M = cv2.getRotationMatrix2D((23.5, 23.5), float(rng.uniform(-20, 20)), 1.0)
    img = cv2.warpAffine(canvas, M, (48, 48), borderMode=cv2.BORDER_REPLICATE)
    img = img * rng.uniform(0.9, 1.1) + rng.uniform(-10, 10) + rng.normal(0, 10, img.shape)
    return np.clip(img, 0, 255).astype(np.float32)


def run_once(
    rng: np.random.Generator,
    tpls: dict[int, np.ndarray],
    modes: tuple[str, ...],
    matcher: str,
    base: np.ndarray,
    process_noise: float = 1.0,
    sharpness: float = 20.0,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """One Monte Carlo run: counts (4 x 5: tracks + none) per mode, and the true routes."""
    from scipy.optimize import linear_sum_assignment

    from pipeline.stages.association import state_log_likelihoods
    from pipeline.stages.roi_match import RoiMatchConfig, image_likelihood, match_rois

    truth = base + np.stack([singer(rng, FRAMES) for _ in range(4)])
    meas = truth + rng.normal(0, math.sqrt(NOISE_VAR_M2), truth.shape)
    chips = [[make_chip(tpls[CLASSES[i]], rng) for _ in range(FRAMES)] for i in range(4)]
    rm = RoiMatchConfig(method=matcher, pad_px=8, sharpness=sharpness, likelihood_floor=1e-6)
    w0 = np.array([[1, 0, 8], [0, 1, 8]], np.float32)
    F = np.array([[1, 0, DT_S, 0], [0, 1, 0, DT_S], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    q = process_noise
    G = np.array([[DT_S**3 / 3, DT_S**2 / 2], [DT_S**2 / 2, DT_S]]) * q
    Q = np.zeros((4, 4))
    Q[np.ix_([0, 2], [0, 2])] = G
    Q[np.ix_([1, 3], [1, 3])] = G
    Hm = np.eye(2, 4)
    R = np.eye(2) * NOISE_VAR_M2
    out = {}
    for mode in modes:
        x = [
            np.array(
                [
                    meas[i, 1, 0],
                    meas[i, 1, 1],
                    (meas[i, 1, 0] - meas[i, 0, 0]) / DT_S,
                    (meas[i, 1, 1] - meas[i, 0, 1]) / DT_S,
                ]
            )
            for i in range(4)
        ]  # two-point start
        P = [
            np.diag(
                [
                    NOISE_VAR_M2,
                    NOISE_VAR_M2,
                    2 * NOISE_VAR_M2 / DT_S**2 + 1,
                    2 * NOISE_VAR_M2 / DT_S**2 + 1,
                ]
            )
            for _ in range(4)
        ]
        tpl_of_track = [chips[i][1][8:40, 8:40] for i in range(4)]
        counts = np.zeros((4, 5))
        for k in range(2, FRAMES):
            cost = np.zeros((4, 4))
            for j in range(4):  # tracks
                xp = F @ x[j]
                Pp = F @ P[j] @ F.T + Q
                x[j], P[j] = xp, Pp
                if mode in ("state", "fused"):
                    S = Hm @ Pp @ Hm.T + R
                    ll, _g = state_log_likelihoods(meas[:, k], xp[:2], S)
                    cost[:, j] -= ll
                if mode in ("image", "fused"):
                    for i in range(4):  # detections
                        rho = match_rois(tpl_of_track[j], chips[i][k], rm, w0).correlation
                        cost[i, j] -= math.log(image_likelihood(rho, rm))
            rows, cols = linear_sum_assignment(cost)
            for i, j in zip(rows, cols, strict=True):
                counts[i, j] += 1
                S = Hm @ P[j] @ Hm.T + R
                K = P[j] @ Hm.T @ np.linalg.inv(S)
                x[j] = x[j] + K @ (meas[i, k] - Hm @ x[j])
                P[j] = (np.eye(4) - K @ Hm) @ P[j]
                tpl_of_track[j] = chips[i][k][8:40, 8:40]
        out[mode] = counts
    return out, truth


def main() -> None:
    import cv2

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--out", type=Path, default=Path("runs/purity_study"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--matcher", choices=("ecc", "gat"), default="ecc")
    ap.add_argument(
        "--process-noise", type=float, default=1.0, help="Kalman q, m^2/s^3 (white acceleration)"
    )
    ap.add_argument(
        "--sharpness",
        type=float,
        default=20.0,
        help="image likelihood exp(-k (1 - rho)); 0 = the paper's max(rho, eps)",
    )
    a = ap.parse_args()
    cv2.setNumThreads(1)
    rng = np.random.default_rng(a.seed)
    tpls = templates()
    base = routes()
    total = {m: np.zeros((4, 5)) for m in MODES}
    example = None
    t0 = time.perf_counter()
    for _ in range(a.runs):
        counts, truth = run_once(rng, tpls, MODES, a.matcher, base, a.process_noise, a.sharpness)
        for m in MODES:
            total[m] += counts[m]
        if example is None:
            example = truth
    frac = {m: total[m] / total[m].sum(axis=1, keepdims=True) for m in MODES}
    result = {m: [[round(float(v), 4) for v in row[:4]] for row in frac[m]] for m in MODES}
    result["none"] = {m: [round(float(v), 4) for v in frac[m][:, 4]] for m in MODES}
    result["diagonal"] = {m: [round(float(frac[m][i, i]), 4) for i in range(4)] for m in MODES}
    result["paper"] = PAPER
    result["settings"] = {
        "runs": a.runs,
        "frames": FRAMES,
        "dt_s": DT_S,
        "noise_var_m2": NOISE_VAR_M2,
        "classes": list(CLASSES),
        "matcher": a.matcher,
        "seed": a.seed,
        "process_noise_m2_per_s3": a.process_noise,
        "image_sharpness": a.sharpness,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "purity.json").write_text(json.dumps(result, indent=1) + "\n")
    from pipeline.sinks.study_plots import purity_figure

    assert example is not None
    purity_figure(a.out / "purity.png", {m: frac[m][:, :4] for m in MODES}, example, PAPER)
    for m in MODES:
        d = result["diagonal"][m]
        print(f"{m:>6}: diagonal {' '.join(f'{v:.3f}' for v in d)}  (mean {np.mean(d):.3f})")
    print(
        f" paper: state {PAPER['state']}, fused {PAPER['fused']}; {a.runs} runs in "
        f"{result['settings']['seconds']} s; "
        f"wrote {a.out / 'purity.json'}"
    )


if __name__ == "__main__":
    main()
