"""A batch's energies in groups of similar object counts: fewer padded edges where small and large
scenes share a batch, the same energies."""

from __future__ import annotations

from collections.abc import Callable

import torch

from ..models import SceneTensors, ScoreModel

__all__ = ["SizeGroups", "best_cuts", "cropped"]


class SizeGroups:
    """A batch's pose sets evaluated in groups of similar object counts, each group cropped to its own
    largest count: the energies of one padded pass to float rounding (padding adds only zeros), with fewer
    ``(N, N)`` edges when scenes of 4 and 24 objects share a batch (``zoo-books``).

    ``counts (S,)``: real objects (walls included) of each scene of the batch, whose pose sets come in
    ``k`` consecutive rows each. Scenes are sorted by count and cut into at most :attr:`MAX_GROUPS`
    contiguous groups where that saves at least a fifth of the edges, else one group (also when not
    ``enabled``).
    """

    MAX_GROUPS = 4

    def __init__(self, counts: torch.Tensor, enabled: bool = True):
        c = counts.tolist()
        order = sorted(range(len(c)), key=lambda i: c[i])
        cuts = best_cuts([c[i] for i in order], self.MAX_GROUPS)
        one = len(c) * max(c) ** 2
        cost = sum((b - a) * c[order[b - 1]] ** 2 for a, b in zip([0, *cuts[:-1]], cuts))
        if cost > 0.8 * one or not enabled:
            cuts = [len(c)]
        self.groups: list[tuple[list[int], int]] = []  # (scene positions, count)
        for a, b in zip([0, *cuts[:-1]], cuts):
            self.groups.append((order[a:b], c[order[b - 1]]))

    def bound(
        self, model: ScoreModel, st: SceneTensors, k: int = 1, weight_grads: bool = True
    ) -> Callable[[torch.Tensor], torch.Tensor]:
        """``poses (S * k, N, 3) -> model.energy(poses, st, weight_grads)`` for ``k`` rows per scene, each
        group's rows, cropped tensors and round objects made once (the chain calls it at every step)."""
        if len(self.groups) == 1:
            return model.energy_for(st, weight_grads)
        parts = []
        for scenes, n in self.groups:
            r = torch.tensor([i * k + j for i in scenes for j in range(k)], device=st.poses.device)
            parts.append((r, n, model.energy_for(cropped(st.index(r), n), weight_grads)))
        order = torch.cat([r for r, _, _ in parts])
        inverse = torch.empty_like(order)
        inverse[order] = torch.arange(len(order), device=order.device)

        def energy(poses: torch.Tensor) -> torch.Tensor:
            return torch.cat([fn(poses[r, :n]) for r, n, fn in parts])[inverse]

        return energy


def cropped(st: SceneTensors, n: int) -> SceneTensors:
    """``st`` with its object axis cut to the first ``n`` (the rest padding)."""
    per_object = ("poses", "feats", "sizes", "mask", "known", "fixed", "round")
    return SceneTensors(
        *(getattr(st, f)[:, :n] if f in per_object else getattr(st, f) for f in st.__dataclass_fields__)
    )


def best_cuts(sorted_counts: list[int], most: int) -> list[int]:
    """Ends of at most ``most`` contiguous groups of ``sorted_counts`` (ascending) that minimise the
    padded edges ``sum(len(group) * max(group) ** 2)`` (dynamic programming over the cut points)."""
    m = len(sorted_counts)
    inf = float("inf")
    best = [[inf] * (m + 1) for _ in range(most + 1)]  # best[g][b]: first b scenes in g groups
    back = [[0] * (m + 1) for _ in range(most + 1)]
    best[0][0] = 0.0
    for g in range(1, most + 1):
        for b in range(1, m + 1):
            for a in range(g - 1, b):
                v = best[g - 1][a] + (b - a) * sorted_counts[b - 1] ** 2
                if v < best[g][b]:
                    best[g][b], back[g][b] = v, a
    g = min(range(1, most + 1), key=lambda j: best[j][m])
    cuts, b = [], m
    while g > 0:
        cuts.append(b)
        b, g = back[g][b], g - 1
    return cuts[::-1]
