"""Motion fitted to recent measurements: the prior a target coasts on while it is hidden.

The Kalman filter's own velocity carries the frame-to-frame jitter of the measurements
(a walking person's CamShift box changes height with every step). When a target
disappears, a least-squares line through its last clean measurements is a steadier
estimate of where it is heading: the slope's standard error falls as ``n^-1.5``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
        raise ValueError(f"history must be (n >= 2, 5) rows of frame, cx, cy, w, h; got shape {h.shape}")
    t = h[:, 0]
    tc = t - t.mean()
    denom = float((tc**2).sum())
    if denom <= 0:
        vx = vy = 0.0
    else:
        vx = float((tc * (h[:, 1] - h[:, 1].mean())).sum() / denom)
        vy = float((tc * (h[:, 2] - h[:, 2].mean())).sum() / denom)
    dt = at_frame - t.mean()
    return LinearFit(float(h[:, 1].mean() + vx * dt), float(h[:, 2].mean() + vy * dt), vx, vy,
                     float(np.median(h[:, 3])), float(np.median(h[:, 4])))
