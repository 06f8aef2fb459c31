"""Rivals: another answer the sampler found, far from the one given, that costs nearly as little.

A sampling solver ends with many particles. When one of them puts an object far from where the answer
puts it (more than :data:`RIVAL_DISTANCE` length scales) and costs at most :data:`RIVAL_MARGIN` more,
the energy cannot tell the two places apart, and which of them is returned hangs on the seed and the
float rounding: a book at the far end of its row rather than beside its neighbour, a nightstand on the
wrong side of the bed. :func:`rivals` names each such object, its distance to the rival place and the
margin, and the learned energy adds it to the object's flags (``rival: ...``).

Objects of one category are interchangeable: a particle that swaps two chairs puts no chair elsewhere.
Each particle's objects are matched to the answer's within each category (the least summed distance,
``scipy.optimize.linear_sum_assignment``) before the distances are taken.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["RIVAL_DISTANCE", "RIVAL_MARGIN", "Rival", "matched_distances", "rivals"]

#: length scales: a particle that puts an object this far from the answer's place is another answer
RIVAL_DISTANCE = 2.0
#: the most a rival may cost above the answer (the objective's units; for placement the learned
#: energy's, where a margin m means the model finds the rival exp(-m) times as likely; docs/studies.md,
#: "The trust check on the zoo")
RIVAL_MARGIN = 1.0


@dataclass(frozen=True)
class Rival:
    """The closest-scoring rival place of one object: how far it is and how much more it costs."""

    distance: float  # metres (the data's length unit)
    margin: float  # the rival's cost minus the answer's, at least 0

    def reason(self, unit: str = "m") -> str:
        return (
            f"rival: another placement {self.distance:.3g} {unit} away costs only {self.margin:.2g} more "
            f"(within {RIVAL_MARGIN}); the model cannot tell the two apart"
        )


def matched_distances(answer: np.ndarray, others: np.ndarray, categories: Sequence[str]) -> np.ndarray:
    """How far each object of ``answer (K, 3)`` is from its match in each row of ``others (B, K, 3)``:
    ``(B, K)``, the objects of a row matched to the answer's one to one within each category, with the
    least summed distance (positions only)."""
    d = np.linalg.norm(others[:, None, :, :2] - answer[None, :, None, :2], axis=-1)  # (B, K answer, K row)
    cats = np.asarray(categories)
    out = np.zeros(others.shape[:2])
    for c in np.unique(cats):
        idx = np.flatnonzero(cats == c)
        if len(idx) == 1:
            out[:, idx[0]] = d[:, idx[0], idx[0]]
            continue
        for b in range(len(others)):
            sub = d[b][np.ix_(idx, idx)]
            rows, cols = linear_sum_assignment(sub)
            out[b, idx[rows]] = sub[rows, cols]
    return out


def rivals(
    answer: np.ndarray,
    others: np.ndarray,
    margins: np.ndarray,
    categories: Sequence[str],
    length_scale: float,
) -> dict[int, Rival]:
    """The rival of each object of ``answer (K, 3)`` that has one, by its index: among the rows of
    ``others (B, K, 3)`` whose cost exceeds the answer's by at most :data:`RIVAL_MARGIN` (``margins
    (B,)``, non-finite ones ignored), the one with the least margin of those that put the object more
    than :data:`RIVAL_DISTANCE` ``length_scale`` from where the answer puts it."""
    margins = np.asarray(margins, dtype=float)
    near = np.isfinite(margins) & (margins <= RIVAL_MARGIN)
    if not near.any():
        return {}
    rows = np.flatnonzero(near)
    dist = matched_distances(
        np.asarray(answer, dtype=float), np.asarray(others, dtype=float)[rows], categories
    )
    out = {}
    for k in range(dist.shape[1]):
        apart = np.flatnonzero(dist[:, k] > RIVAL_DISTANCE * length_scale)
        if len(apart):
            j = apart[np.argmin(margins[rows[apart]])]
            out[k] = Rival(float(dist[j, k]), max(0.0, float(margins[rows[j]])))
    return out
