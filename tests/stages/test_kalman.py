"""Kalman stage against closed-form predict/update."""

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from pipeline.stages import kalman
from pipeline.types import BBox


def test_constant_acceleration_matrices():
    cfg = kalman.KalmanConfig(dt_frames=2.0, position_noise=0.5, size_noise=0.1)
    F, Q = kalman.motion_model(cfg)
    assert F.shape == Q.shape == (12, 12)
    # x' = x + dt v + dt^2/2 a for every coordinate
    s = np.arange(12, dtype=float)
    np.testing.assert_allclose((F @ s)[:4], s[:4] + 2 * s[4:8] + 2 * s[8:12])
    # white-jerk block for x: q * [[dt^5/20, dt^4/8, dt^3/6], ...]
    dt = 2.0
    blk = 0.5 * np.array(
        [
            [dt**5 / 20, dt**4 / 8, dt**3 / 6],
            [dt**4 / 8, dt**3 / 3, dt**2 / 2],
            [dt**3 / 6, dt**2 / 2, dt],
        ]
    )
    np.testing.assert_allclose(Q[np.ix_([0, 4, 8], [0, 4, 8])], blk)
    np.testing.assert_allclose(Q[np.ix_([2, 6, 10], [2, 6, 10])], blk / 5)
    assert Q[0, 1] == 0 and not F.flags.writeable


def test_constant_velocity_variant():
    cfg = kalman.KalmanConfig(model="constant_velocity", position_noise=1.0)
    F, Q = kalman.motion_model(cfg)
    H, _R = kalman.measurement_model(cfg)
    assert F.shape == (8, 8) and H.shape == (4, 8)
    np.testing.assert_allclose(Q[np.ix_([0, 4], [0, 4])], [[1 / 3, 1 / 2], [1 / 2, 1]])


def test_predict_and_update_closed_form():
    cfg = kalman.KalmanConfig()
    F, Q = kalman.motion_model(cfg)
    H, R = kalman.measurement_model(cfg)
    rng = np.random.default_rng(0)
    A = rng.normal(size=(12, 12))
    P = A @ A.T + np.eye(12)
    x = rng.normal(size=12)
    prior = kalman.predict(kalman.GaussianState(x, P), F, Q)
    np.testing.assert_allclose(prior.x, F @ x, atol=1e-12)
    np.testing.assert_allclose(prior.P, F @ P @ F.T + Q, atol=1e-10)
    z = np.array([3.0, -2.0, 30.0, 40.0])
    up = kalman.update(prior, z, H, R)
    S = H @ prior.P @ H.T + R
    K = prior.P @ H.T @ np.linalg.inv(S)
    np.testing.assert_allclose(up.innovation, z - H @ prior.x, atol=1e-12)
    np.testing.assert_allclose(up.S, S, atol=1e-10)
    np.testing.assert_allclose(up.state.x, prior.x + K @ (z - H @ prior.x), atol=1e-9)
    np.testing.assert_allclose(up.state.P, (np.eye(12) - K @ H) @ prior.P, atol=1e-8)
    y = up.innovation
    assert up.mahalanobis == pytest.approx(np.sqrt(y @ np.linalg.inv(S) @ y))
    assert kalman.log_likelihood(y, S) == pytest.approx(
        multivariate_normal(np.zeros(4), S).logpdf(y)
    )


@pytest.mark.parametrize("model", ["constant_acceleration", "constant_velocity"])
def test_predict_and_update_equal_filterpy_bit_for_bit(model):
    from filterpy.kalman import predict as fp_predict
    from filterpy.kalman import update as fp_update

    cfg = kalman.KalmanConfig(model=model)
    F, Q = kalman.motion_model(cfg)
    H, R = kalman.measurement_model(cfg)
    rng = np.random.default_rng(7)
    for fading in (1.0, 1.3):
        for _ in range(50):
            A = rng.normal(0, 3, (cfg.dim, cfg.dim))
            st = kalman.GaussianState(rng.normal(0, 50, cfg.dim), A @ A.T + np.eye(cfg.dim))
            x, P = fp_predict(st.x.reshape(-1, 1), st.P, F, Q, alpha=np.sqrt(fading))
            prior = kalman.predict(st, F, Q, fading)
            assert np.array_equal(prior.x, x.ravel()) and np.array_equal(prior.P, P)
            z = rng.normal(0, 50, 4)
            x, P = fp_update(prior.x.reshape(-1, 1), prior.P, z.reshape(-1, 1), R, H)
            up = kalman.update(prior, z, H, R)
            assert np.array_equal(up.state.x, x.ravel()) and np.array_equal(up.state.P, P)
            assert np.array_equal(up.S, H @ prior.P @ H.T + R)


def test_fading_memory_scales_the_propagated_covariance():
    cfg = kalman.KalmanConfig()
    F, Q = kalman.motion_model(cfg)
    st = kalman.init_state(BBox(0, 0, 10, 20), cfg)
    a = kalman.predict(st, F, Q, fading=1.5)
    np.testing.assert_allclose(a.P, 1.5 * F @ st.P @ F.T + Q, atol=1e-10)


def test_init_state_and_coasting():
    cfg = kalman.KalmanConfig()
    st = kalman.init_state(BBox(10, 20, 30, 40), cfg)
    np.testing.assert_allclose(st.x[:4], [25, 40, 30, 40])
    assert st.box == BBox(10, 20, 30, 40)
    np.testing.assert_allclose(np.diag(st.P)[4:8], 25.0)
    F, Q = kalman.motion_model(cfg)
    s = kalman.GaussianState(np.r_[st.x[:4], 2.0, -1.0, 0, 0, np.zeros(4)], st.P)
    for _ in range(5):  # repeated prediction without a measurement coasts
        s = kalman.predict(s, F, Q)
    np.testing.assert_allclose(s.x[:2], [35, 35])
    assert np.all(np.diag(s.P) > np.diag(st.P) - 1e-9)


def test_filters_a_constant_velocity_target():
    cfg = kalman.KalmanConfig()
    F, Q = kalman.motion_model(cfg)
    H, R = kalman.measurement_model(cfg)
    rng = np.random.default_rng(1)
    s = kalman.init_state(BBox(0, 0, 20, 40), cfg)
    vel, pos_err = [], []
    for k in range(1, 200):
        truth = np.array([10 + 3.0 * k, 20 - 1.0 * k])
        z = np.r_[truth, 20, 40] + rng.normal(0, [3, 3, 5, 5])
        s = kalman.update(kalman.predict(s, F, Q), z, H, R).state
        if k > 50:
            vel.append(s.x[4:6])
            pos_err.append(s.x[:2] - truth)
    np.testing.assert_allclose(np.mean(vel, axis=0), [3.0, -1.0], atol=0.3)
    assert (
        np.sqrt(np.mean(np.square(pos_err))) < 3.0
    )  # filtered position beats the 3 px measurement noise


@pytest.mark.parametrize("kw", [dict(model="singer"), dict(dt_frames=0), dict(position_std_px=-1)])
def test_bad_config(kw):
    with pytest.raises(ValueError):
        kalman.KalmanConfig(**kw)


@pytest.mark.parametrize("adaptive", [False, True])
def test_the_compiled_filter_is_the_numpy_one(adaptive):
    """``predict_compiled`` / ``correct_compiled`` over 200 frames of a target that accelerates,
    measured with noise at several measurement noises, with and without the manoeuvre
    inflation: the same states, innovations and S as ``predict`` / ``correct`` to 1e-9 relative
    (on this machine bit for bit)."""

    cfg = kalman.KalmanConfig(maneuver_adaptive=adaptive)
    F, Q = kalman.motion_model(cfg)
    H, R = kalman.measurement_model(cfg)
    rng = np.random.default_rng(3)
    state = kalman.init_state(BBox(100, 100, 20, 50), cfg)
    for i in range(200):
        prior, fast = kalman.predict(state, F, Q), kalman.predict_compiled(state, F, Q)
        np.testing.assert_allclose(fast.x, prior.x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(fast.P, prior.P, rtol=1e-9, atol=1e-9)
        z = kalman.box_measurement(
            BBox(100 + 0.05 * i * i + rng.normal(0, 3), 100 + 2 * i, 20 + rng.normal(), 50)
        )
        r = R * rng.uniform(0.5, 3.0)
        ref, got = (
            kalman.correct(prior, z, H, r, cfg),
            kalman.correct_compiled(prior, z, H, r, cfg),
        )
        for a, b in (
            (got.state.x, ref.state.x),
            (got.state.P, ref.state.P),
            (got.innovation, ref.innovation),
            (got.S, ref.S),
        ):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
        state = ref.state
