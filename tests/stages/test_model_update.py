"""Selective sub-model update (eq. 8-9) against hand-computed values."""

import numpy as np
import pytest

from pipeline.stages.model_update import (
    ModelUpdateConfig,
    anchored_bins,
    matching_contribution,
    selective_update,
    should_update_model,
)


def test_mcd_eq8():
    p = np.array([0.5, 0.5, 0.0, 0.0])
    q = np.array([0.5, 0.125, 0.375, 0.0])
    s = np.sqrt(p * q)
    np.testing.assert_allclose(matching_contribution(p, q), s / s.sum())
    assert matching_contribution(np.eye(2)[0], np.eye(2)[1]).sum() == 0


def test_update_all_three_cases_by_hand():
    q = np.array([0.5, 0.125, 0.375, 0.0])
    p = np.array([0.5, 0.25, 0.0, 0.25])
    cfg = ModelUpdateConfig(model_rate=0.1, rank_rule="count", rank_count=1)
    mcd = matching_contribution(p, q)  # bins 0 and 1 > 0; bins 2 and 3 are 0
    new = np.array(
        [
            0.5,  # case 2: top-ranked bin (rank 1 <= k = 1) unchanged
            mcd[1] * 0.25 + (1 - mcd[1]) * 0.125,  # case 3: MCD-weighted blend
            0.1 * 0.0 + 0.9 * 0.375,  # case 1: absent from the candidate, fades at model_rate
            0.1 * 0.25 + 0.9 * 0.0,  # case 1: new colour enters at model_rate
        ]
    )
    np.testing.assert_allclose(selective_update(q, p, cfg), new / new.sum())


def test_rank_rules():
    mcd = np.array([0.5, 0.3, 0.15, 0.05, 0.0])
    assert anchored_bins(
        mcd, ModelUpdateConfig(rank_rule="cumulative", rank_mass=0.8)
    ).tolist() == [True, True, False, False, False]
    assert anchored_bins(
        mcd, ModelUpdateConfig(rank_rule="cumulative", rank_mass=0.81)
    ).tolist() == [True, True, True, False, False]
    assert anchored_bins(mcd, ModelUpdateConfig(rank_rule="count", rank_count=3)).sum() == 3
    assert anchored_bins(mcd, ModelUpdateConfig(rank_rule="above_average")).tolist() == [
        True,
        True,
        False,
        False,
        False,
    ]


def test_decision_gate_and_reasons():
    cfg = ModelUpdateConfig()
    assert str(should_update_model(0.9, False, True, True, cfg)) == "updated:rho-high"
    assert str(should_update_model(0.7, False, True, True, cfg)) == "frozen:rho-low"
    assert str(should_update_model(0.95, True, True, True, cfg)) == "frozen:occluded"
    assert str(should_update_model(0.95, False, False, True, cfg)) == "frozen:colour-uninformative"
    assert str(should_update_model(0.95, False, True, False, cfg)) == "frozen:no-contour"
    assert (
        str(should_update_model(0.95, False, True, True, ModelUpdateConfig(enabled=False)))
        == "frozen:disabled"
    )


@pytest.mark.parametrize(
    "kw", [dict(model_rate=1.5), dict(rank_rule="top"), dict(rank_mass=0), dict(min_rho=2)]
)
def test_bad_config(kw):
    with pytest.raises(ValueError):
        ModelUpdateConfig(**kw)


def test_compiled_update_equals_eq9_written_in_numpy_to_the_last_bit():
    """The default (``cumulative``) rule runs compiled: on random sparse histograms, empty
    matches and identical ones it gives eq. 9 as the numpy steps give it, bit for bit."""
    cfg = ModelUpdateConfig()
    rng = np.random.default_rng(3)
    for t in range(400):
        q = rng.random(256) * (rng.random(256) < 0.3)
        p = np.zeros(256) if t % 7 == 0 else rng.random(256) * (rng.random(256) < 0.3)
        if t % 11 == 0:
            p = q.copy()
        q /= q.sum()
        p /= max(p.sum(), 1e-300)
        mcd = matching_contribution(p, q)
        top = anchored_bins(mcd, cfg)
        ref = q.copy()
        zero = mcd == 0
        ref[zero] = cfg.model_rate * p[zero] + (1 - cfg.model_rate) * q[zero]
        rest = (mcd > 0) & ~top
        ref[rest] = mcd[rest] * p[rest] + (1 - mcd[rest]) * q[rest]
        ref = ref / ref.sum()
        assert np.array_equal(selective_update(q, p, cfg), ref)
