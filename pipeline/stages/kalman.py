"""Kalman motion stage over the box ``(x, y, w, h)`` (centre and size, px), shared by every
tracker.

Two models, ``dt`` = 1 frame by default (the Kalman-CAMShift paper's 12-state model and
a constant-velocity variant)::

    constant acceleration:  s = [x, y, w, h, x', y', w', h', x'', y'', w'', h'']  (12)
        F = [[I, dt I, dt^2/2 I], [0, I, dt I], [0, 0, I]] Q = q * [[dt^5/20, dt^4/8, dt^3/6],
        [dt^4/8, dt^3/3, dt^2/2], [dt^3/6, dt^2/2, dt]]   (white jerk)
    constant velocity:      s = [x, y, w, h, x', y', w', h']                          (8)
        F = [[I, dt I], [0, I]] Q = q * [[dt^3/3, dt^2/2], [dt^2/2, dt]]
        (white acceleration)

with ``q`` = ``position_noise`` for x, y and ``size_noise`` for w, h; ``z = H s = (x, y, w, h)``
and ``R = diag(sigma_p^2, sigma_p^2, sigma_s^2, sigma_s^2)``.

The algebra is filterpy's (``filterpy.kalman.predict`` / ``update``, Joseph-form
posterior), written out here operation for operation so that the per-frame path skips its
argument handling and the innovation is not computed twice (tests compare the two bit for bit).
``cv2.KalmanFilter`` was the other candidate; it is a mutable object (our states are
frozen values), hides the innovation covariance S (only in its undocumented ``temp3``)
and needs float32 matrices of exact shape. State vectors are 1-D in this API.

:func:`predict_compiled` and :func:`correct_compiled` are the same algebra as one compiled call
each (a few microseconds against tens for numpy's small matrix calls); they sum in another order
than BLAS, so they agree with :func:`predict` / :func:`correct` to rounding (tested to 1e-9
relative), not bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, lru_cache

import numba
import numpy as np

from pipeline.params import Section, param
from pipeline.types import BBox


@dataclass(frozen=True)
class KalmanConfig(Section):
    """Motion model and noise of the Kalman stage.

    Parameters
    ----------
    model : str
        ``constant_acceleration`` (12 states, the Kalman-CAMShift paper's) or
        ``constant_velocity`` (8 states); default ``constant_acceleration``.
    dt_frames : float
        Time step, frames, > 0; default 1.
    position_noise : float
        Process noise intensity q of x, y, (px/frame^3)^2 for the white-jerk model or
        (px/frame^2)^2 for the white-acceleration model, > 0; default 0.01. Increasing
        it follows manoeuvres faster and trusts the prediction less during occlusion,
        and makes the velocity carried through an occlusion noisier.
    size_noise : float
        Process noise intensity q of w, h (same units), > 0; default 0.005.
    position_std_px : float
        Measurement noise sigma of the box centre, px, > 0; default 3.
    size_std_px : float
        Measurement noise sigma of the box size, px, > 0; default 5.
    initial_velocity_std_px_per_frame : float
        Prior sigma of the velocities at initialisation, px/frame, > 0; default 5.
    initial_acceleration_std_px_per_frame2 : float
        Prior sigma of the accelerations at initialisation, px/frame^2, > 0; default 1.
    maneuver_adaptive : bool
        Inflate the predicted covariance when the innovation says the target manoeuvres
        (the fused-image CHNN paper's eq. 23-25, :func:`maneuver_factor`); default False.
    maneuver_sigma : float
        The test's sigma multiplier (the paper's D in eq. 23-24, not its image weight): an
        innovation component beyond this many sigma counts as a manoeuvre, > 0; default 3.
    maneuver_cap : float
        Largest inflation factor, >= 1; default 100.
    """

    section = "kalman"

    model: str = param(
        "constant_acceleration", choices=("constant_acceleration", "constant_velocity")
    )
    dt_frames: float = param(1.0, gt=0)
    position_noise: float = param(0.01, gt=0)
    size_noise: float = param(0.005, gt=0)
    position_std_px: float = param(3.0, gt=0)
    size_std_px: float = param(5.0, gt=0)
    initial_velocity_std_px_per_frame: float = param(5.0, gt=0)
    initial_acceleration_std_px_per_frame2: float = param(1.0, gt=0)
    maneuver_adaptive: bool = False
    maneuver_sigma: float = param(3.0, gt=0)
    maneuver_cap: float = param(100.0, ge=1)

    @property
    def order(self) -> int:
        """Number of derivative blocks: 3 (x, x', x'') or 2 (x, x')."""
        return 3 if self.model == "constant_acceleration" else 2

    @property
    def dim(self) -> int:
        return 4 * self.order


@dataclass(frozen=True)
class GaussianState:
    """A state estimate: mean ``x`` (n,) and covariance ``P`` (n, n)."""

    x: np.ndarray
    P: np.ndarray

    @property
    def box(self) -> BBox:
        """The (x, y, w, h) part as a box (centre + size -> corner convention)."""
        cx, cy, w, h = (float(v) for v in self.x[:4])
        return BBox.from_center(cx, cy, max(w, 1.0), max(h, 1.0))

    @property
    def velocity(self) -> tuple[float, float]:
        return float(self.x[4]), float(self.x[5])


@dataclass(frozen=True)
class KalmanUpdate:
    """Result of a measurement update: the posterior and the innovation ``y`` with covariance
    ``S``."""

    state: GaussianState
    innovation: np.ndarray
    S: np.ndarray

    @property
    def mahalanobis(self) -> float:
        """sqrt(y^T S^-1 y)."""
        return float(np.sqrt(self.innovation @ np.linalg.solve(self.S, self.innovation)))


def _blocks(order: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """1-D transition and white-noise (unit intensity) blocks for one coordinate."""
    if order == 3:
        f = np.array([[1, dt, dt * dt / 2], [0, 1, dt], [0, 0, 1]], float)
        q = np.array(
            [
                [dt**5 / 20, dt**4 / 8, dt**3 / 6],
                [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                [dt**3 / 6, dt**2 / 2, dt],
            ]
        )
    else:
        f = np.array([[1, dt], [0, 1]], float)
        q = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    return f, q


@lru_cache(maxsize=64)
def motion_model(cfg: KalmanConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(F, Q)`` of the configured model, states ordered ``[x, y, w, h, derivatives...]`` (cached;
    treat the arrays as read-only)."""
    f, q = _blocks(cfg.order, cfg.dt_frames)
    intensity = np.diag([cfg.position_noise, cfg.position_noise, cfg.size_noise, cfg.size_noise])
    F = np.kron(f, np.eye(4))  # blocks by derivative order, each a 4x4 diagonal
    Q = np.kron(q, intensity)
    F.flags.writeable = False
    Q.flags.writeable = False
    return F, Q


@lru_cache(maxsize=64)
def measurement_model(cfg: KalmanConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(H, R)``: the filter observes ``(x, y, w, h)`` (cached; read-only arrays)."""
    H = np.zeros((4, cfg.dim))
    H[:, :4] = np.eye(4)
    p, s = cfg.position_std_px**2, cfg.size_std_px**2
    R = np.diag([p, p, s, s])
    H.flags.writeable = False
    R.flags.writeable = False
    return H, R


def box_measurement(box: BBox) -> np.ndarray:
    """``z = (cx, cy, w, h)`` of a box."""
    return np.array([box.cx, box.cy, box.w, box.h], float)


def init_state(box: BBox, cfg: KalmanConfig) -> GaussianState:
    """State at the first detection: the box, zero velocity and acceleration, P0 = diag(R, v^2 I,
    a^2 I)."""
    x = np.zeros(cfg.dim)
    x[:4] = box_measurement(box)
    _, R = measurement_model(cfg)
    var = [np.diag(R)]
    var.append(np.full(4, cfg.initial_velocity_std_px_per_frame**2))
    if cfg.order == 3:
        var.append(np.full(4, cfg.initial_acceleration_std_px_per_frame2**2))
    return GaussianState(x, np.diag(np.concatenate(var)))


def predict(
    state: GaussianState, F: np.ndarray, Q: np.ndarray, fading: float = 1.0
) -> GaussianState:
    """Prior of the next step: ``x = F x``, ``P = fading * F P F^T + Q`` (fading 1 = plain Kalman).

    filterpy's ``predict`` operation for operation (``alpha = sqrt(fading)``, column state),
    without its argument handling; equal to it bit for bit (tested)."""
    alpha = np.sqrt(fading)
    x = (
        np.dot(F, state.x.reshape(-1, 1)) + 0.0
    )  # filterpy adds dot(B, u) = 0 (turning -0.0 into 0.0)
    P = (alpha * alpha) * np.dot(np.dot(F, state.P), F.T) + Q
    return GaussianState(x.ravel(), P)


def innovation(
    prior: GaussianState, z: np.ndarray, H: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Innovation ``y = z - H x`` and its covariance ``S = H P H^T + R`` (no update)."""
    y = np.asarray(z, float) - H @ prior.x
    S = H @ prior.P @ H.T + R
    return y, S


def update(prior: GaussianState, z: np.ndarray, H: np.ndarray, R: np.ndarray) -> KalmanUpdate:
    """Posterior after measuring ``z`` (4,), with the innovation and its covariance.

    filterpy's ``update`` (Joseph form) operation for operation on column vectors, without its
    argument handling, and with the innovation and S it computes; equal to it bit for bit (tested).
    """
    y, S = innovation(prior, z, H, R)
    P0 = prior.P
    K = np.dot(np.dot(P0, H.T), np.linalg.inv(S))
    x = prior.x.reshape(-1, 1) + np.dot(K, y.reshape(-1, 1))
    I_KH = np.eye(K.shape[0]) - np.dot(K, H)
    P = np.dot(np.dot(I_KH, P0), I_KH.T) + np.dot(np.dot(K, R), K.T)
    return KalmanUpdate(GaussianState(x.ravel(), P), y, S)


def maneuver_factor(
    prior: GaussianState, z: np.ndarray, H: np.ndarray, R: np.ndarray, sigma: float
) -> float:
    """a_max of eq. 23-25: per measured component i, with innovation tau_i, delta_ii =
    [H P H^T]_ii and R_ii, a_i = ((tau_i / sigma)^2 - R_ii) / delta_ii (the factor that
    makes |tau_i| = sigma sqrt(a_i delta_ii + R_ii)); a_i > 1 exactly when |tau_i| >
    sigma sqrt(S_ii). Returns max_i a_i."""
    tau = np.asarray(z, float) - H @ prior.x
    delta = np.diag(H @ prior.P @ H.T)
    a = ((tau / sigma) ** 2 - np.diag(R)) / np.maximum(delta, 1e-12)
    return float(a.max())


def correct(
    prior: GaussianState, z: np.ndarray, H: np.ndarray, R: np.ndarray, cfg: KalmanConfig
) -> KalmanUpdate:
    """:func:`update`, after inflating the predicted covariance by ``a_max`` (capped) when
    ``cfg.maneuver_adaptive`` and the innovation says the target manoeuvres (a_max > 1)."""
    return update(_maneuvered(prior, z, H, R, cfg), z, H, R)


def _maneuvered(
    prior: GaussianState, z: np.ndarray, H: np.ndarray, R: np.ndarray, cfg: KalmanConfig
) -> GaussianState:
    """``prior`` with its covariance inflated by ``a_max`` (capped) when ``cfg.maneuver_adaptive``
    and the innovation of ``z`` says the target manoeuvres (a_max > 1); else ``prior``."""
    if cfg.maneuver_adaptive:
        a = maneuver_factor(prior, z, H, R, cfg.maneuver_sigma)
        if a > 1.0:
            return GaussianState(prior.x, prior.P * min(a, cfg.maneuver_cap))
    return prior


def log_likelihood(y: np.ndarray, S: np.ndarray) -> float:
    """Gaussian log-density of the innovation: ``-(y^T S^-1 y + ln|2 pi S|) / 2``."""
    _sign, logdet = np.linalg.slogdet(2 * np.pi * S)
    return float(-0.5 * (y @ np.linalg.solve(S, y) + logdet))


def predict_compiled(
    state: GaussianState, F: np.ndarray, Q: np.ndarray, fading: float = 1.0
) -> GaussianState:
    """:func:`predict` in one compiled call (equal to it within rounding). ``F`` and ``Q`` as
    :func:`motion_model` gives them (read-only float64: the signature the kernel is compiled
    for once; the state is copied)."""
    alpha = np.sqrt(fading)
    x, P = _predict_kernel(
        np.array(state.x, np.float64), np.array(state.P, np.float64), F, Q, float(alpha * alpha)
    )
    return GaussianState(x, P)


def correct_compiled(
    prior: GaussianState, z: np.ndarray, H: np.ndarray, R: np.ndarray, cfg: KalmanConfig
) -> KalmanUpdate:
    """:func:`correct` with :func:`update`'s algebra in one compiled call (equal to it within
    rounding). ``H`` as :func:`measurement_model` gives it (read-only float64); the rest is
    copied, so that the kernel is compiled for one signature."""
    z = np.array(z, np.float64)
    prior = _maneuvered(prior, z, H, R, cfg)
    x, P, y, S = _update_kernel(
        np.array(prior.x, np.float64), np.array(prior.P, np.float64), z, H, np.array(R, np.float64)
    )
    return KalmanUpdate(GaussianState(x, P), y, S)


@numba.njit(cache=True, nogil=True)
def _mul(A, B):  # pragma: no cover (compiled)
    """A @ B of two small float64 matrices, plain loops."""
    n, m = A.shape
    p = B.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a = A[i, k]
            if a != 0.0:
                for j in range(p):
                    out[i, j] += a * B[k, j]
    return out


@numba.njit(cache=True, nogil=True)
def _predict_kernel(x, P, F, Q, a2):  # pragma: no cover (compiled)
    """``(F x, a2 F P F^T + Q)``."""
    n = x.size
    xo = np.zeros(n)
    for i in range(n):
        s = 0.0
        for k in range(n):
            s += F[i, k] * x[k]
        xo[i] = s
    Po = _mul(_mul(F, P), F.T.copy())
    for i in range(n):
        for j in range(n):
            Po[i, j] = a2 * Po[i, j] + Q[i, j]
    return xo, Po


@numba.njit(cache=True, nogil=True)
def _update_kernel(x, P, z, H, R):  # pragma: no cover (compiled)
    """Posterior (Joseph form), innovation and its covariance, as :func:`update`."""
    n, m = x.size, z.size
    y = np.empty(m)
    for i in range(m):
        s = 0.0
        for k in range(n):
            s += H[i, k] * x[k]
        y[i] = z[i] - s
    Ht = H.T.copy()
    PHt = _mul(P, Ht)
    S = _mul(H, PHt)
    for i in range(m):
        for j in range(m):
            S[i, j] += R[i, j]
    K = _mul(PHt, np.linalg.inv(S))
    xo = x.copy()
    for i in range(n):
        s = 0.0
        for k in range(m):
            s += K[i, k] * y[k]
        xo[i] += s
    I_KH = -_mul(K, H)
    for i in range(n):
        I_KH[i, i] += 1.0
    Po = _mul(_mul(I_KH, P), I_KH.T.copy()) + _mul(_mul(K, R), K.T.copy())
    return xo, Po, y, S


@cache
def warm_up() -> None:
    """Compile or load the compiled filter's kernels once per process."""
    cfg = KalmanConfig()
    F, Q = motion_model(cfg)
    H, R = measurement_model(cfg)
    prior = predict_compiled(init_state(BBox(0.0, 0.0, 10.0, 10.0), cfg), F, Q)
    correct_compiled(prior, np.zeros(4), H, R, cfg)
