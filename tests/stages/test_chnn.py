"""CHNN association (one-to-one, equals Hungarian where unambiguous, energy never rises) and the
manoeuvre-adaptive Kalman step (eq. 23-25)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.stages import kalman
from pipeline.stages.association import hungarian
from pipeline.stages.chnn import (
    BIG,
    chnn,
    chnn_associator,
    cost_matrix,
    energy,
    hungarian_reference,
)


def test_cost_matrix_layout():
    d = cost_matrix(np.array([[0.5, 4.0], [1.0, 2.0]]), gate_radius=3.0)
    assert d.shape == (4, 2)
    assert d[0, 0] == 3.0 and d[1, 1] == 3.0 and d[0, 1] == BIG and d[1, 0] == BIG  # pseudo rows
    assert (
        d[2, 0] == 0.5 and d[3, 0] == BIG and d[2, 1] == 1.0 and d[3, 1] == 2.0
    )  # gated measurement rows


@pytest.mark.parametrize(
    "distance, expected",
    [
        (
            np.array([[0.2, 2.5, 2.9], [2.6, 0.4, 2.8]]),
            [2, 3],
        ),  # each its own, the third is clutter
        (np.array([[0.2, 5.0], [0.3, 5.0]]), [2, 1]),  # both want m0: target 1 coasts
        (np.array([[4.0, 5.0], [6.0, 7.0]]), [0, 1]),  # nothing in the gates: both coast
        (
            np.array([[0.3, 2.0, 9.0], [9.0, 0.4, 2.2], [9.0, 9.0, 0.1]]),
            [3, 4, 5],
        ),  # three targets, a chain
    ],
)
def test_chnn_is_one_to_one_and_equals_hungarian_on_clear_cases(distance, expected):
    d = cost_matrix(distance, 3.03)
    res = chnn(d, A=1.0, B=3.03 + 1.0, init="pseudo")
    ref, _ = hungarian_reference(d)
    assert list(res.rows) == expected == list(ref)
    meas = [r for r in res.rows if r >= d.shape[1]]
    assert len(meas) == len(set(meas))  # no measurement feeds two targets
    assert res.converged


def test_a_local_minimum_is_possible_and_measured():
    """Winner-take-all moves one column at a time: it cannot make the 2-swap that reaches
    the optimum here (docs/algorithms.md §6); the Hungarian reference shows the gap."""
    d = cost_matrix(np.array([[1.0, 1.1], [1.05, 2.9]]), 3.03)
    res = chnn(d, A=1.0, B=4.03, init="pseudo")
    ref, best = hungarian_reference(d)
    assert list(ref) == [3, 2] and best == pytest.approx(2.15)
    mine = float(d[res.rows, [0, 1]].sum())
    assert list(res.rows) == [2, 3] and mine == pytest.approx(3.9)  # stuck: 1.0 + 2.9
    assert list(chnn(d, A=1.0, B=4.03, init="nearest").rows) == [
        3,
        2,
    ]  # from nearest neighbours it gets there


def test_energy_never_increases():
    rng = np.random.default_rng(0)
    for _ in range(200):
        n, m = rng.integers(1, 6), rng.integers(0, 9)
        d = cost_matrix(rng.uniform(0, 5, (n, m)), 3.03)
        F = rng.uniform(0, 1, d.shape) * (d < BIG)
        for init in ("nearest", "pseudo"):
            res = chnn(d, A=1.0, B=4.03, F=F, image_weight=1.0, init=init)
            e = np.array(res.energies)
            assert (np.diff(e) <= 1e-9).all(), e
            V = np.zeros_like(d)
            V[res.rows, np.arange(n)] = 1
            assert e[-1] == pytest.approx(energy(V, d + 1.0 * F, 4.03))


def test_associator_interface_matches_hungarian_and_reports_the_gap():
    cost = np.array([[1.0, 20.0, 6.0], [15.0, 2.0, 7.0]])
    miss, new = np.full(2, 2.3), np.full(3, 9.2)
    a = chnn_associator(cost, miss, new)
    h = hungarian(cost, miss, new)
    assert sorted(a.pairs) == sorted(h.pairs) == [(0, 0), (1, 1)] and a.cost == pytest.approx(
        h.cost
    )
    assert a.details["gap_to_optimum"] == pytest.approx(0.0) and a.details["sweeps"] >= 1
    from pipeline.trackers.detect import ASSOCIATORS

    assert ASSOCIATORS["chnn"] is chnn_associator
    assert chnn_associator(
        np.zeros((0, 2)), np.zeros(0), np.full(2, 1.0)
    ).unmatched_detections == (0, 1)


def test_adaptive_step_inflates_p_exactly_by_eq25():
    kcfg = kalman.KalmanConfig(
        model="constant_velocity", maneuver_adaptive=True, maneuver_sigma=2.0
    )
    H, R = kalman.measurement_model(kcfg)
    P = np.diag([9.0, 16.0, 4.0, 4.0, 1.0, 1.0, 1.0, 1.0])
    prior = kalman.GaussianState(np.array([100.0, 50.0, 20.0, 40.0, 0, 0, 0, 0]), P)
    z = np.array([130.0, 52.0, 20.0, 40.0])  # 30 px off in x: a manoeuvre
    tau = z - H @ prior.x
    delta = np.diag(H @ P @ H.T)
    a = ((tau / 2.0) ** 2 - np.diag(R)) / delta
    a_max = float(a.max())
    assert kalman.maneuver_factor(prior, z, H, R, 2.0) == pytest.approx(a_max)
    assert a_max > 1 and abs(tau[0]) > 2.0 * np.sqrt(delta[0] + R[0, 0])
    got = kalman.correct(prior, z, H, R, kcfg)
    want = kalman.update(kalman.GaussianState(prior.x, P * a_max), z, H, R)
    np.testing.assert_allclose(got.state.x, want.state.x)
    np.testing.assert_allclose(got.state.P, want.state.P)
    # inside D sigma: no inflation
    calm = np.array([101.0, 50.5, 20.0, 40.0])
    assert kalman.maneuver_factor(prior, calm, H, R, 2.0) < 1
    np.testing.assert_allclose(
        kalman.correct(prior, calm, H, R, kcfg).state.P, kalman.update(prior, calm, H, R).state.P
    )
    # off by default
    off = kalman.correct(prior, z, H, R, kalman.KalmanConfig(model="constant_velocity"))
    np.testing.assert_allclose(off.state.P, kalman.update(prior, z, H, R).state.P)
