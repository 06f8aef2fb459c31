"""The examples' own relations as a cost: a density over each category pair's relative poses, no training.

``ExampleRelations(scenes)`` keeps, for every pair of categories ``(c, a)`` the example scenes hold, the
pose of every object of ``c`` in the frame of every object of ``a`` of its scene. At a pose set, each
moving object ``i`` of category ``c`` and each other object ``j`` of category ``a`` add ``-log(floor +
mean_k exp(-d_k^2 / 2))``, where ``d_k`` is how far ``i``'s pose in ``j``'s frame lies from the ``k``-th
example pose, its position over :data:`BANDWIDTH` times half ``i``'s longer side and its heading over
:data:`HEADING_BANDWIDTH` (no heading for a round object or in a round anchor's frame, whose heading
is arbitrary: by the distance alone). Pairs the examples never show add nothing. The floor keeps an
arrangement the examples never showed finite and its gradient small. It is exact on what it saw and
says nothing beyond it; summed with the learned energy it adds the examples' relations to the
network's. As a guide it proposes each moving object at an example pose beside a known object.
``ExampleRelations.of_model(model)`` reads the relations a checkpoint keeps of its training scenes;
in a problem file, ``{type: examples}``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
import torch
from torch import Tensor

from ..geometry.poses import compose_poses, relative_poses
from ..runtime import draw
from ..scene.scene import Scene
from .base import Cost
from .guide import Guide
from .spec import CostSpec, SpecContext, register_cost_type
from .terms import CostError

__all__ = ["ExampleRelations", "ExamplesSpec", "BANDWIDTH", "HEADING_BANDWIDTH", "FLOOR"]

BANDWIDTH = 0.5  # the position kernel's width, in halves of the placed object's longer side
HEADING_BANDWIDTH = 0.3  # radians
FLOOR = math.exp(-6.0)  # the density floor: an unseen relation costs at most 6 per pair
MAX_ROWS = 512  # example poses kept per category pair (evenly spaced)


def _tables(scenes: Sequence[Scene]) -> dict[tuple[str, str], np.ndarray]:
    """``{(category, anchor category): poses (K, 3)}``: every object's pose in every other object's frame."""
    found: dict[tuple[str, str], list[np.ndarray]] = {}
    for s in scenes:
        if s.unknown:
            raise CostError(f"ExampleRelations: an example scene has objects without a pose ({s.unknown})")
        p = torch.as_tensor(s.poses(), dtype=torch.float64)
        rel = relative_poses(p[:, None], p[None, :]).numpy()  # (anchor, object, 3)
        for a, anchor in enumerate(s.objects):
            for o, obj in enumerate(s.objects):
                if a != o:
                    found.setdefault((obj.category, anchor.category), []).append(rel[a, o])
    out = {}
    for key, rows in sorted(found.items()):
        arr = np.stack(rows)
        if len(arr) > MAX_ROWS:
            arr = arr[np.linspace(0, len(arr) - 1, MAX_ROWS).round().astype(int)]
        out[key] = arr
    return out


class ExampleRelations(Cost, Guide):
    """The non-parametric relational energy of ``scenes`` (see the module's description)."""

    needs_scene = True

    def __init__(self, scenes: Sequence[Scene], name: str = "examples"):
        if not scenes:
            raise CostError("ExampleRelations: give at least one example scene")
        self.tables = _tables(scenes)
        self.name = name
        self._pairs: list[tuple[int, int, Tensor, float, bool, bool]] = []

    @classmethod
    def of_model(cls, model: Any, name: str = "examples") -> ExampleRelations:
        """The relations a trained model's checkpoint keeps of its training scenes (its trust reference's
        :attr:`~scenescore.models.trust.TrustReference.relations`: at most
        :data:`~scenescore.models.layout.RELATIONS_PER_PAIR` poses per category pair, evenly chosen),
        so that no example file is needed. CostError for a model without them."""
        ref = getattr(model, "trust", None)
        if ref is None or not ref.relations:
            raise CostError("ExampleRelations: the model's checkpoint keeps no relations of its examples")
        out = cls.__new__(cls)
        out.tables = {
            (c, a): np.asarray(rows, dtype=np.float64) * np.array([ref.length_scale, ref.length_scale, 1.0])
            for c, by_anchor in sorted(ref.relations.items())
            for a, rows in sorted(by_anchor.items())
            if rows
        }
        out.name, out._pairs = name, []
        return out

    def _on_bind(self) -> None:
        b = self.binding
        objs = b.scene.objects
        self._pairs = []
        for i in np.flatnonzero(b.movable).tolist():
            for j, a in enumerate(objs):
                rows = self.tables.get((objs[i].category, a.category))
                if j == i or rows is None:
                    continue
                width = BANDWIDTH * max(objs[i].size) / 2
                t = torch.as_tensor(rows, dtype=torch.float64, device=b.device)
                self._pairs.append((i, j, t, width, a.round, objs[i].round or a.round))

    def evaluate(self, poses: Tensor) -> Tensor:
        out = poses.new_zeros(poses.shape[0])
        for i, j, rows, width, round_anchor, no_heading in self._pairs:
            rel = relative_poses(poses[:, j], poses[:, i])  # (B, 3)
            r = rows.to(poses.dtype)
            if round_anchor:  # by the distance alone
                d = (rel[:, None, :2].norm(dim=-1) - r[None, :, :2].norm(dim=-1)) / width
                d2 = d * d
            else:
                d2 = ((rel[:, None, :2] - r[None, :, :2]) ** 2).sum(-1) / width**2
            if not no_heading:
                d2 = d2 + 2 * (1 - torch.cos(rel[:, None, 2] - r[None, :, 2])) / HEADING_BANDWIDTH**2
            density = torch.exp(-0.5 * d2).mean(dim=1)
            out = out - torch.log(FLOOR + density)
        return out

    def propose(self, x: Tensor, generator: torch.Generator) -> Tensor | None:
        """``x (B, N, 3)`` with each moving object put at an example pose beside a known object of the
        scene (one of every such pose drawn uniformly by ``generator``); None without a known anchor."""
        b = self.binding
        out, drawn = x.clone(), False
        for i in np.flatnonzero(b.movable).tolist():
            beside = [(j, rows) for (ii, j, rows, *_) in self._pairs if ii == i and not b.movable[j]]
            if not beside:
                continue
            at = torch.cat([torch.full((len(r),), j, device=x.device) for j, r in beside])
            rel = torch.cat([r for _, r in beside]).to(x.dtype)
            u = draw("rand", (x.shape[0],), generator, x.device, torch.float64)
            pick = (u * len(at)).long().clamp(max=len(at) - 1)
            out[:, i] = compose_poses(x[torch.arange(x.shape[0], device=x.device), at[pick]], rel[pick])
            drawn = True
        return out if drawn else None


class ExamplesSpec(CostSpec):
    """``{type: examples, weight, name, model}``: the relations the problem file's model (or the
    checkpoint ``model`` names, relative to the file) keeps of its training scenes."""

    type: Literal["examples"]
    model: str | None = None

    def build(self, ctx: SpecContext) -> Cost:
        model = ctx.model(("model",)) if self.model is None else ctx.checkpoint(self.model, ("model",))
        return ExampleRelations.of_model(model, **self.named())


register_cost_type("examples", ExamplesSpec)
