"""Global association with dummies: hand-built optima, empty sides, the state likelihood."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.stages.association import (
    AssociationConfig,
    hungarian,
    padded_cost,
    state_log_likelihood,
)


def test_empty_sides():
    a = hungarian(np.zeros((0, 3)), np.zeros(0), np.full(3, 5.0))
    assert a.pairs == () and a.unmatched_detections == (0, 1, 2) and a.cost == 15.0
    a = hungarian(np.zeros((2, 0)), np.full(2, 1.5), np.zeros(0))
    assert a.pairs == () and a.unmatched_tracks == (0, 1) and a.cost == 3.0
    a = hungarian(np.zeros((0, 0)), np.zeros(0), np.zeros(0))
    assert a.pairs == () and a.cost == 0.0


def test_global_optimum_not_greedy_and_dummies():
    cost = np.array([[1.0, 2.0], [1.5, 9.0]])
    a = hungarian(cost, np.full(2, 20.0), np.full(2, 20.0))
    assert sorted(a.pairs) == [(0, 1), (1, 0)] and a.cost == pytest.approx(3.5)
    # a pair dearer than "missed + new" is split into a miss and a birth
    a = hungarian(np.array([[30.0]]), np.array([2.0]), np.array([9.0]))
    assert (
        a.pairs == ()
        and a.unmatched_tracks == (0,)
        and a.unmatched_detections == (0,)
        and a.cost == 11.0
    )
    # impossible (gated out) pairs never assign
    a = hungarian(np.array([[np.inf, 1.0], [np.inf, 2.0]]), np.full(2, 3.0), np.full(2, 4.0))
    assert a.pairs == ((0, 1),) and a.unmatched_tracks == (1,) and a.unmatched_detections == (0,)
    big = padded_cost(np.array([[1.0, 2.0]]), np.array([3.0]), np.array([4.0, 5.0]))
    assert (
        big.shape == (3, 3)
        and big[0, 2] == 3.0
        and big[1, 0] == 4.0
        and big[2, 1] == 5.0
        and big[1, 1] > 1e8
    )
    assert (big[1:, 2:] == 0).all()


def test_state_likelihood_is_the_gaussian_density():
    S = np.array([[4.0, 1.0], [1.0, 9.0]])
    d = np.array([1.0, -2.0])
    ll, gamma = state_log_likelihood(np.array([11.0, 18.0]), np.array([10.0, 20.0]), S)
    assert gamma == pytest.approx(d @ np.linalg.inv(S) @ d)
    expected = math.exp(-gamma / 2) / (2 * math.pi * math.sqrt(np.linalg.det(S)))
    assert math.exp(ll) == pytest.approx(expected)


def test_config_is_checked():
    with pytest.raises(ValueError):
        AssociationConfig(use_image=False, use_state=False)
    with pytest.raises(ValueError):
        AssociationConfig(confirm_hits=6, confirm_window=5)
