"""Competitive Hopfield neural network (CHNN) data association, with an image term.

The associator of the fused-image CHNN paper (its eq. 17-22), as docs/algorithms.md §6 lays it
out. The neuron matrix V is (N + M) x N: columns are the N targets, rows 0..N-1 their
pseudo-measurements ("no measurement for target i"), rows N..N+M-1 the M measurements.

* costs d (eq. 17): the plain Mahalanobis distance of measurement x to target i inside the
  gate, the gate radius λ on the target's own pseudo row, "∞" (a large finite number) for
  another target's pseudo row and outside the gate;
* the image term (eq. 19-22): F_{x,i} = 1 - R_{x,i}, a *dissimilarity* (the paper prints F
  as if larger were better, but a larger F raises the energy; 1 - R prefers good matches),
  weighted by ``image_weight`` (the paper's D = 100; not the maneuver test's D);
* energy E = Σ (A d + W F) V / 2 + (B/2) Σ_x Σ_i Σ_{j≠i} V_{x,i} V_{x,j} (row inhibition:
  one measurement must not feed two targets); net input
  Net_{x,i} = -(A d_{x,i} + W F_{x,i}) / 2 - B Σ_{j≠i} V_{x,j};
* winner-take-all per target column (eq. 18), columns updated one at a time and swept
  until a sweep changes nothing; with B > (A/2) λ the fixed point is one-to-one. Every
  column move lowers or keeps E (the recorded energies never increase).

:func:`chnn` returns the assignment, the energy after every column update and the sweeps;
:func:`hungarian_reference` solves the same cost exactly, so the energy gap to the
optimum can be reported per frame. :func:`chnn_associator` adapts it to the associator
interface of ``pipeline.stages.association`` (``association.associator = chnn``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.stages.association import IMPOSSIBLE, Assignment

BIG = 1e9


@dataclass(frozen=True)
class ChnnResult:
    """Winner row per target column (< N: its pseudo row, no measurement; else N + measurement),
    the energy after the initial state and after every column update, the sweeps made, and
    whether a sweep changed nothing before ``max_sweeps``."""

    rows: np.ndarray
    energies: tuple[float, ...]
    sweeps: int
    converged: bool

    def measurement_of(self, n_targets: int) -> list[int | None]:
        """Measurement index per target (None: no measurement)."""
        return [int(r) - n_targets if r >= n_targets else None for r in self.rows]


def cost_matrix(distance: np.ndarray, gate_radius: float) -> np.ndarray:
    """The (N + M) x N matrix d of eq. 17 from the N x M Mahalanobis distances: pseudo rows
    (λ on the diagonal, BIG elsewhere) above the measurement rows (BIG beyond the gate)."""
    n, m = distance.shape
    d = np.full((n + m, n), BIG)
    d[np.arange(n), np.arange(n)] = gate_radius
    real = np.asarray(distance, float).T.copy()
    real[~np.isfinite(real) | (real > gate_radius)] = BIG
    d[n:, :] = real
    return d


def energy(V: np.ndarray, cost: np.ndarray, B: float) -> float:
    """E = Σ cost V / 2 + (B/2) Σ_x Σ_i Σ_{j≠i} V_{x,i} V_{x,j} (``cost`` = A d + W F)."""
    row = V.sum(axis=1)
    return float(0.5 * (cost * V).sum() + 0.5 * B * (row * row - (V * V).sum(axis=1)).sum())


def chnn(
    d: np.ndarray,
    A: float = 1.0,
    B: float | None = None,
    F: np.ndarray | None = None,
    image_weight: float = 100.0,
    max_sweeps: int = 50,
    init: str = "nearest",
) -> ChnnResult:
    """Run the network on the (N + M) x N cost ``d`` (and dissimilarity ``F``, same shape).

    ``B`` defaults to the paper's λ + 1 with λ read off the pseudo diagonal; ``init`` is
    ``nearest`` (each column at its cheapest row) or ``pseudo`` (every target at its pseudo row).
    """
    d = np.asarray(d, float)
    _rows_total, n = d.shape
    if n == 0:
        return ChnnResult(np.zeros(0, int), (0.0,), 0, True)
    lam = float(np.diag(d[:n, :n]).max())
    B = lam + 1.0 if B is None else B
    cost = A * d + (image_weight * np.asarray(F, float) if F is not None else 0.0)
    V = np.zeros_like(d)
    if init == "pseudo":
        winners = np.arange(n)
    else:
        winners = np.argmin(cost, axis=0)
    V[winners, np.arange(n)] = 1.0
    energies = [energy(V, cost, B)]
    sweeps = 0
    converged = False
    while sweeps < max_sweeps:
        sweeps += 1
        changed = False
        for i in range(n):
            others = V.sum(axis=1) - V[:, i]  # Σ_{j≠i} V_{x,j}
            net = -0.5 * cost[:, i] - B * others
            best = int(np.argmax(net))
            cur = int(np.argmax(V[:, i]))
            if best != cur and net[best] > net[cur]:
                V[cur, i] = 0.0
                V[best, i] = 1.0
                changed = True
            energies.append(energy(V, cost, B))
        if not changed:
            converged = True
            break
    return ChnnResult(np.argmax(V, axis=0), tuple(energies), sweeps, converged)


def hungarian_reference(
    d: np.ndarray, F: np.ndarray | None = None, A: float = 1.0, image_weight: float = 100.0
) -> tuple[np.ndarray, float]:
    """Exact minimum of Σ (A d + W F) over one-to-one assignments: winner row per column and its
    cost."""
    cost = A * np.asarray(d, float) + (
        image_weight * np.asarray(F, float) if F is not None else 0.0
    )
    r, c = linear_sum_assignment(cost)
    rows = np.empty(cost.shape[1], int)
    rows[c] = r
    return rows, float(cost[r, c].sum())


def assignment_cost(
    rows: np.ndarray,
    d: np.ndarray,
    F: np.ndarray | None = None,
    A: float = 1.0,
    image_weight: float = 100.0,
) -> float:
    cost = A * np.asarray(d, float) + (
        image_weight * np.asarray(F, float) if F is not None else 0.0
    )
    return float(cost[rows, np.arange(len(rows))].sum())


def chnn_associator(cost: np.ndarray, miss_cost: np.ndarray, new_cost: np.ndarray) -> Assignment:
    """CHNN with the associator interface: track n's pseudo row costs ``miss_cost[n]``, and
    measurement j's row ``cost - new_cost[j]`` (the same total as the Hungarian's padded
    problem, up to the constant Σ new_cost). ``details``: the energies, sweeps, and the gap
    to the Hungarian optimum of the same matrix."""
    cost = np.asarray(cost, float)
    n, m = cost.shape
    if n == 0 or m == 0:
        return Assignment(
            (),
            tuple(range(n)),
            tuple(range(m)),
            float(np.sum(miss_cost)) + float(np.sum(new_cost)),
        )
    # Σ pairs + Σ missed + Σ unassigned detections = Σ new + Σ pairs (cost - new_j) + Σ missed:
    # a measurement row costs what taking it saves over leaving the detection to a new track
    d = np.full((n + m, n), BIG)
    d[np.arange(n), np.arange(n)] = miss_cost
    real = cost.T - np.asarray(new_cost, float)[:, None]
    real[~np.isfinite(cost.T) | (cost.T >= IMPOSSIBLE)] = BIG
    d[n:, :] = real
    # row inhibition above half of (dearest pseudo row - cheapest measurement row): one-to-one
    # fixed points
    finite = real[real < BIG]
    B = float(np.max(miss_cost)) - (float(finite.min()) if finite.size else 0.0) + 1.0
    res = chnn(d, A=1.0, B=B, image_weight=0.0)
    _ref_rows, ref_cost = hungarian_reference(d, image_weight=0.0)
    rows = res.rows
    mine = assignment_cost(rows, d, image_weight=0.0)
    pairs = tuple((i, int(r) - n) for i, r in enumerate(rows) if r >= n and d[r, i] < BIG)
    used = {j for _, j in pairs}
    total = mine + float(np.sum(new_cost))
    return Assignment(
        pairs,
        tuple(i for i in range(n) if i not in {p[0] for p in pairs}),
        tuple(j for j in range(m) if j not in used),
        total,
        {"energies": res.energies, "sweeps": res.sweeps, "gap_to_optimum": mine - ref_cost},
    )
