"""Selective sub-model update (eq. 8-9 of the dual-channel paper, after Shen, Yang, Huang 2009).

Matching contribution degree of every bin (eq. 8)::

    MCD_u = sqrt(p_u q_u) / sum_v sqrt(p_v q_v)

with ``p`` the candidate histogram measured in the visible frame at the contour position
y2 with the updated scale and ``q`` the model. Update (eq. 9), then renormalization (C_q):

1. ``MCD_u = 0`` (bin absent from the model or the candidate): ``q_u <- a p_u + (1 - a) q_u``,
   ``a`` = ``model_rate`` (the paper reuses the letter alpha): new colours enter slowly and
   vanished ones fade slowly;
2. ``MCD_u > 0`` and ``u <= k``: ``q_u`` unchanged: the bins that match best anchor the model;
3. ``MCD_u > 0`` and ``u > k``: ``q_u <- MCD_u p_u + (1 - MCD_u) q_u``.

Reading of ``k`` (the paper does not define it; docs/algorithms.md §3): bins are ranked by MCD
in descending order and ``u <= k`` means rank <= k. ``rank_rule`` chooses k: ``cumulative``
(default; the smallest k whose cumulative MCD reaches ``rank_mass`` = 0.8), ``count``
(a fixed ``rank_count``), or ``above_average`` (every bin whose MCD exceeds the mean MCD
of the non-zero bins).

The decision whether to update at all is :func:`should_update_model`, kept apart from the
arithmetic so the reason can be reported (targets.csv ``model_update``, the .rrd events).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numba
import numpy as np

from pipeline.params import Section, param
from pipeline.stages.histogram import np_sum


@dataclass(frozen=True)
class ModelUpdateConfig(Section):
    """Selective sub-model update.

    Parameters
    ----------
    enabled : bool
        Update the appearance model at all; default True.
    model_rate : float
        a of eq. 9 case 1, learning rate of bins absent from model or candidate, in [0, 1];
        default 0.1. Increasing it adopts new colours (and forgets vanished ones) faster.
    rank_rule : str
        How k of eq. 9 is chosen: ``cumulative``, ``count`` or ``above_average``; default
        ``cumulative``.
    rank_mass : float
        Cumulative MCD that the k best bins must reach (``cumulative`` rule), in (0, 1];
        default 0.8. Increasing it freezes more bins.
    rank_count : int
        k for the ``count`` rule, >= 0; default 16.
    min_rho : float
        Update only when the Bhattacharyya coefficient at y2 is at least this, in [0, 1];
        default 0.8 (docs/algorithms.md §3). Increasing it updates less often and more safely.
    """

    section = "model_update"

    enabled: bool = True
    model_rate: float = param(0.1, ge=0, le=1)
    rank_rule: str = param("cumulative", choices=("cumulative", "count", "above_average"))
    rank_mass: float = param(0.8, gt=0, le=1)
    rank_count: int = param(16, ge=0)
    min_rho: float = param(0.8, ge=0, le=1)


def matching_contribution(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """MCD_u of eq. 8 (all zeros when the histograms share no bin)."""
    s = np.sqrt(p * q)
    total = s.sum()
    return s / total if total > 0 else np.zeros_like(s)


def anchored_bins(mcd: np.ndarray, cfg: ModelUpdateConfig) -> np.ndarray:
    """Boolean mask of the bins with ``u <= k`` (kept unchanged by case 2)."""
    order = np.argsort(-mcd, kind="stable")
    positive = mcd[order] > 0
    if cfg.rank_rule == "count":
        k = min(cfg.rank_count, int(positive.sum()))
    elif cfg.rank_rule == "above_average":
        nz = mcd[mcd > 0]
        k = int((mcd > nz.mean()).sum()) if nz.size else 0
    else:
        cum = np.cumsum(mcd[order])
        k = int(np.searchsorted(cum, cfg.rank_mass - 1e-12) + 1) if positive.any() else 0
        k = min(k, int(positive.sum()))
    mask = np.zeros(mcd.shape, bool)
    mask[order[:k]] = True
    return mask


def selective_update(q: np.ndarray, p: np.ndarray, cfg: ModelUpdateConfig) -> np.ndarray:
    """Eq. 9: the updated, renormalized model (``q`` and ``p`` are not modified)."""
    if q.shape != p.shape:
        raise ValueError(f"q and p must have the same shape; got {q.shape} vs {p.shape}")
    if (
        cfg.rank_rule == "cumulative"
        and q.ndim == 1
        and q.dtype == np.float64
        and p.dtype == np.float64
    ):  # the lines below, compiled
        return _selective_update_cumulative(q, p, float(cfg.model_rate), float(cfg.rank_mass))
    mcd = matching_contribution(p, q)
    top = anchored_bins(mcd, cfg)
    new = q.astype(np.float64, copy=True)
    zero = mcd == 0
    new[zero] = cfg.model_rate * p[zero] + (1 - cfg.model_rate) * q[zero]
    rest = (mcd > 0) & ~top
    new[rest] = mcd[rest] * p[rest] + (1 - mcd[rest]) * q[rest]
    total = new.sum()
    return new / total if total > 0 else q.copy()


@numba.njit(cache=True, boundscheck=False, nogil=True, error_model="numpy")
def _selective_update_cumulative(q, p, model_rate, rank_mass):  # pragma: no cover (compiled)
    """:func:`selective_update` with the ``cumulative`` rank rule, compiled: the same float64
    operations in the same order (numpy's pairwise sums, a stable sort, sequential cumulative
    sums), so the same model to the last bit."""
    m = q.size
    s = np.empty(m, np.float64)
    for u in range(m):
        s[u] = np.sqrt(p[u] * q[u])
    total = np_sum(s)
    mcd = np.zeros(m, np.float64)
    if total > 0:
        for u in range(m):
            mcd[u] = s[u] / total
    neg = np.empty(m, np.float64)
    for u in range(m):
        neg[u] = -mcd[u]
    order = np.argsort(neg, kind="mergesort")
    n_pos = 0
    for u in range(m):
        n_pos += mcd[u] > 0
    k = 0
    if n_pos > 0:
        cum = np.empty(m, np.float64)
        acc = 0.0
        for i in range(m):
            acc += mcd[order[i]]
            cum[i] = acc
        k = min(int(np.searchsorted(cum, rank_mass - 1e-12)) + 1, n_pos)
    top = np.zeros(m, np.bool_)
    for i in range(k):
        top[order[i]] = True
    new = q.copy()
    for u in range(m):
        if mcd[u] == 0:
            new[u] = model_rate * p[u] + (1 - model_rate) * q[u]
        elif mcd[u] > 0 and not top[u]:
            new[u] = mcd[u] * p[u] + (1 - mcd[u]) * q[u]
    t = np_sum(new)
    if t > 0:
        for u in range(m):
            new[u] = new[u] / t
        return new
    return q.copy()


@dataclass(frozen=True)
class UpdateDecision:
    """Whether to update the model this frame, and why (``decision:reason`` in targets.csv)."""

    update: bool
    reason: str

    def __str__(self) -> str:
        return f"{'updated' if self.update else 'frozen'}:{self.reason}"


def should_update_model(
    rho_at_y2: float,
    occluded: bool,
    colour_informative: bool,
    contour_ok: bool,
    cfg: ModelUpdateConfig,
) -> UpdateDecision:
    """Gate of the update: never while occluded, in an uninformative (dark) visible frame, or
    without a contour position, and only when the match at y2 is good."""
    if not cfg.enabled:
        return UpdateDecision(False, "disabled")
    if occluded:
        return UpdateDecision(False, "occluded")
    if not colour_informative:
        return UpdateDecision(False, "colour-uninformative")
    if not contour_ok:
        return UpdateDecision(False, "no-contour")
    if rho_at_y2 < cfg.min_rho:
        return UpdateDecision(False, "rho-low")
    return UpdateDecision(True, "rho-high")


@cache
def warm_up() -> None:
    """Compile or load the compiled update once per process."""
    _selective_update_cumulative(np.full(4, 0.25), np.full(4, 0.25), 0.1, 0.8)
