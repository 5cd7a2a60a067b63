"""Motion fitted to recent measurements: the prior a target coasts on while it is hidden.

The Kalman filter's own velocity carries the frame-to-frame jitter of the measurements
(a walking person's CamShift box changes height with every step). When a target
disappears, a least-squares line through its last clean measurements is a steadier
estimate of where it is heading: the slope's standard error falls as ``n^-1.5``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.stages import kalman


@dataclass(frozen=True)
class LinearFit:
    """Position (at the requested frame), velocity per frame and median size of a track."""

    cx: float
    cy: float
    vx: float
    vy: float
    w: float
    h: float


def fit_linear_motion(history: np.ndarray, at_frame: float) -> LinearFit:
    """Least-squares straight-line fit of ``history`` rows ``(frame, cx, cy, w, h)``.

    Parameters
    ----------
    history : (n, 5) array, n >= 2
        Clean measurements, any order.
    at_frame : float
        Frame at which the position is evaluated.

    Returns
    -------
    LinearFit
    """
    h = np.asarray(history, float)
    if h.ndim != 2 or h.shape[1] != 5 or h.shape[0] < 2:
        raise ValueError(
            f"history must be (n >= 2, 5) rows of frame, cx, cy, w, h; got shape {h.shape}"
        )
    t = h[:, 0]
    tc = t - t.mean()
    denom = float((tc**2).sum())
    if denom <= 0:
        vx = vy = 0.0
    else:
        vx = float((tc * (h[:, 1] - h[:, 1].mean())).sum() / denom)
        vy = float((tc * (h[:, 2] - h[:, 2].mean())).sum() / denom)
    dt = at_frame - t.mean()
    return LinearFit(
        float(h[:, 1].mean() + vx * dt),
        float(h[:, 2].mean() + vy * dt),
        vx,
        vy,
        float(np.median(h[:, 3])),
        float(np.median(h[:, 4])),
    )


def hold_rates(kf: kalman.GaussianState, kcfg: kalman.KalmanConfig) -> kalman.GaussianState:
    """Zero the size rates and all accelerations: a hidden target coasts at constant velocity and
    size."""
    x = kf.x.copy()
    x[6:8] = 0.0
    if kcfg.order == 3:
        x[8:] = 0.0
    return kalman.GaussianState(x, kf.P)


def stop(kf: kalman.GaussianState) -> kalman.GaussianState:
    """Zero every rate (velocity, size rate, acceleration): the state of a target given up as
    lost."""
    x = kf.x.copy()
    x[4:] = 0.0
    return kalman.GaussianState(x, kf.P)


def coast_start(
    history: tuple[tuple[float, float, float, float, float], ...],
    prior: kalman.GaussianState,
    frame: int,
    max_age_frames: int,
    drop_newest: int = 0,
    tolerance: float = math.inf,
) -> kalman.GaussianState | None:
    """State to coast from when an occlusion starts: position, velocity and size from a straight
    line through the recent clean measurements ``(frame, cx, cy, w, h)``, leaving out the
    ``drop_newest`` newest (an occluder often cuts the target before the cut is detected). None
    when fewer than 4 remain, the newest is older than ``max_age_frames``, or ``max_age_frames`` is
    0, and also when a left-out measurement lies farther from the line than ``tolerance`` times
    the size on either axis (the target turned: the line is the motion it had before).

    Examples
    --------
    >>> from pipeline.stages import kalman
    >>> prior = kalman.GaussianState(np.zeros(8), np.eye(8))
    >>> walk = [(f, 10.0 * f, 50.0, 10.0, 20.0) for f in range(1, 9)]
    >>> coast_start(walk, prior, 9, 8, 2).x[:6].round(1).tolist()  # straight on: rewound
    [90.0, 50.0, 10.0, 20.0, 10.0, 0.0]
    >>> back = walk[:6] + [(7, 50.0, 50.0, 10.0, 20.0), (8, 40.0, 50.0, 10.0, 20.0)]
    >>> coast_start(back, prior, 9, 8, 2, tolerance=0.5) is None  # turned back: not rewound
    True
    """
    hist = np.asarray(history, float).reshape(-1, 5)
    keep = hist.shape[0] - drop_newest if hist.shape[0] - drop_newest >= 4 else hist.shape[0]
    hist, left_out = hist[:keep], hist[keep:]
    if max_age_frames == 0 or hist.shape[0] < 4 or frame - hist[-1, 0] > max_age_frames:
        return None
    fit = fit_linear_motion(hist, frame)
    for f, cx, cy, _w, _h in left_out:
        dt = f - frame
        if (
            abs(cx - (fit.cx + fit.vx * dt)) > tolerance * fit.w
            or abs(cy - (fit.cy + fit.vy * dt)) > tolerance * fit.h
        ):
            return None
    x = np.zeros_like(prior.x)
    x[:6] = (fit.cx, fit.cy, fit.w, fit.h, fit.vx, fit.vy)
    return kalman.GaussianState(x, prior.P)
