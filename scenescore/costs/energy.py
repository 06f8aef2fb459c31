"""The learned energy as a cost: ``E(poses | scene)`` of a trained model."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Literal, cast

import casadi as ca
import numpy as np
import torch
from torch import Tensor

from ..geometry.poses import compose_poses
from ..models import ScoreModel
from ..models.casadi import energy_mx
from ..models.explain import Explanation, explain
from ..models.flags import assess
from ..models.model import with_walls
from ..models.moving import Mover, stack_movers
from ..models.network import round_flags
from ..models.rivals import rivals
from ..models.trust import CAVEAT, RELATION, Assessment, outside_data
from ..runtime import draw
from ..scene.scene import Scene
from ..scene.units import length_unit
from .base import Cost
from .guide import Alternatives, Guide, Verdict
from .spec import CostSpec, SpecContext, register_cost_type
from .symbolic import SymbolicProblem, objective_by_torch, register_casadi_form
from .terms import CostError, check_scene_names

__all__ = ["LearnedEnergy", "EnergySpec"]


class LearnedEnergy(Cost, Guide):
    """The trained energy ``E(poses | scene)``, conditioned on the bound scene's objects.

    ``objects``: the names the energy sees (default: all). Objects left out, such as clutter of a
    class the model never saw, are invisible to it and only enter through the other costs.

    As a :class:`~scenescore.costs.guide.Guide` it judges poses by the model's trust reference
    (:mod:`scenescore.models.trust`: the poses its training data has): it proposes poses beside the
    scene's known objects, doubts pose sets that put a moving object where the data never had one of
    its category, and gives each moving object a confidence (:class:`~scenescore.models.trust.Assessment`).

    ``relations``: whether a flagged object's flags end with the relation it doubts (:meth:`doubted`, an
    explanation by integrated gradients over the whole scene, the costliest part of a verdict); False
    where only the flags' count is read, as in a validation's table (the same flags otherwise).
    """

    needs_scene = True
    doubt_note = "put an object where its data has none (at a bound, far from the rest, or from a category)"

    def __init__(
        self,
        model: ScoreModel,
        name: str = "energy",
        objects: Sequence[str] | None = None,
        relations: bool = True,
    ):
        if not hasattr(model, "energy_fn"):
            raise CostError(
                f"LearnedEnergy: expected a ScoreModel (scenescore.models.load), got {type(model).__name__}"
            )
        if objects is not None and (isinstance(objects, str) or len(objects) == 0):
            raise CostError(
                f"LearnedEnergy: objects: expected a non-empty list of object names, got {objects!r}"
            )
        self.model = model
        self.name = name
        self.objects = None if objects is None else list(objects)
        self.relations = relations
        self._fn: Callable[[Tensor], Tensor] | None = None
        self._mover: Mover | None = None  # where one object moves (set when bound)
        self._idx: Tensor | None = None
        self.visible_scene: Scene | None = None

    @property
    def visible(self) -> list[int]:
        """Indices of the bound scene's objects that the energy sees."""
        n = len(self.binding.scene)
        return list(range(n)) if self._idx is None else [int(i) for i in self._idx]

    def model_device(self) -> torch.device:
        """The model's device: a problem with this term runs there unless told otherwise."""
        return self.model.device

    def _on_bind(self) -> None:
        scene = self.binding.scene
        if self.binding.device != self.model.device:
            raise CostError(
                f"LearnedEnergy {self.name!r}: the model is on {self.model.device}, the problem on "
                f"{self.binding.device}; load the model there (models.load(path, device=...)) or move it "
                "(model.to(device))"
            )
        self._idx = None
        if self.objects is not None:
            idx = check_scene_names(scene, self.objects, f"LearnedEnergy {self.name!r}: objects")
            scene = type(scene)([scene.objects[i] for i in idx], scene.bounds, meta=scene.meta)
            self._idx = torch.tensor(idx, dtype=torch.long, device=self.binding.device)
        self.visible_scene = scene  # the scene the energy is conditioned on
        with torch.no_grad():
            st = self.model.tensors([scene])
            self._fn = self.model.energy_fn_for(st)
        moving = [i for i, m in enumerate(self.binding.movable) if m]
        one = self.objects is None and len(moving) == 1
        self._mover = self.model.moving_one(st, moving[0]) if one else None

    @classmethod
    def stack(cls, terms: Sequence[Cost], sizes: Sequence[int]) -> Callable[[Tensor], Tensor]:
        """Fused: one network call for every group when the terms share a model and see every object."""
        es = [t for t in terms if isinstance(t, LearnedEnergy)]
        if len(es) != len(terms) or any(t.model is not es[0].model or t.objects is not None for t in es):
            return super().stack(terms, sizes)
        model = es[0].model
        with torch.no_grad():
            st = model.tensors([t.binding.scene for t in es])
            nodes = model.net.node_embedding(st.feats, st.sizes)  # (G, N, D)
        reps = torch.as_tensor(list(sizes), device=model.device)
        rows = torch.arange(len(es), device=model.device).repeat_interleave(reps)
        st = st.repeat(1).index(rows)  # one row per particle
        nodes = nodes.repeat_interleave(reps, dim=0)
        rnd = round_flags(model.config, st.round)

        def fn(poses: Tensor) -> Tensor:
            x = with_walls(poses.to(model.dtype), st)
            e = model.net(x, None, None, st.mask, nodes=nodes, round=rnd, weight_grads=False)
            return e.to(poses.dtype)

        movers = [t._mover for t in es]
        if any(m is None for m in movers):
            return fn
        widths = [len(t.binding.scene) for t in es]
        together = stack_movers(cast(list[Mover], movers), sizes) if len(set(widths)) == 1 else None

        def moving(poses: Tensor) -> Tensor:
            """Each problem's one moving object through its own evaluator (all or none of them), the
            problems' evaluators stacked into one where they share the network and the width."""
            x = poses.to(model.dtype)
            if together is not None:
                e = together(x[:, : widths[0]])
                return fn(poses) if e is None else e.to(poses.dtype)
            parts, a = [], 0
            for m, size, n in zip(movers, sizes, widths):
                e = m(x[a : a + size, :n])  # type: ignore[misc]
                if e is None:
                    return fn(poses)
                parts.append(e)
                a += size
            return torch.cat(parts).to(poses.dtype)

        return moving

    def _moving(self) -> list[str]:
        """The names of the movable objects that the energy sees."""
        return [self.binding.scene.names[i] for i in self.visible if self.binding.movable[i]]

    def _seen_at(self, poses: np.ndarray) -> Scene | None:
        """The scene the energy sees, at the bound scene's ``poses (N, 3)``; None when unbound."""
        if self.visible_scene is None:
            return None
        return self.visible_scene.with_poses(np.asarray(poses)[self.visible])

    def verdicts(self, poses: np.ndarray) -> dict[str, Assessment]:
        """Confidence and flags of the moving objects the energy sees, against the model's trust reference."""
        ref, scene = self.model.trust, self._seen_at(poses)
        if ref is None or scene is None:
            return {}
        moving = self._moving()
        return assess(ref, self.model, scene, moving) if moving else {}

    def explain(
        self, poses: np.ndarray, name: str | None = None, scenes: Sequence[Scene] | None = None
    ) -> Explanation:
        """What holds the moving object ``name`` (default: the one moving object the energy sees) at
        ``poses (N, 3)`` of the bound scene (:func:`~scenescore.models.explain.explain`; ``scenes``: the
        example scenes, to name the ones showing each relation)."""
        scene = self._seen_at(poses)
        if scene is None:
            raise CostError(f"LearnedEnergy {self.name!r}: bind it to a scene before explaining")
        if name is None:
            moving = self._moving()
            if len(moving) != 1:
                raise ValueError(f"explain: name the object to explain, one of {', '.join(moving) or 'none'}")
            name = moving[0]
        return explain(self.model, scene, name, scenes)

    def rivals(self, poses: np.ndarray, alternatives: Alternatives) -> dict[str, str]:
        """The moving objects that another of the ``alternatives`` puts more than
        :data:`~scenescore.models.rivals.RIVAL_DISTANCE` length scales away for at most
        :data:`~scenescore.models.rivals.RIVAL_MARGIN` more cost (:func:`~scenescore.models.rivals.rivals`;
        objects of one category matched), each with its ``rival: ...`` reason."""
        if self.visible_scene is None:
            return {}
        moving = self._moving()
        if not moving:
            return {}
        idx = [self.binding.scene.index(n) for n in moving]
        found = rivals(
            np.asarray(poses)[idx],
            np.asarray(alternatives.poses)[:, idx],
            alternatives.margins,
            [self.binding.scene[n].category for n in moving],
            float(self.model.config.length_scale),
        )
        unit = length_unit(self.visible_scene)
        return {moving[k]: r.reason(unit) for k, r in found.items()}

    def doubted(self, poses: np.ndarray, flagged: Mapping[str, Verdict]) -> dict[str, str]:
        """For each object the energy sees that a flag doubts (the model's own caveats about its
        training are no doubt of the pose), the relation it doubts: the strongest of the energy's holds
        on the object that no example shows, else the strongest, with how the examples bear it out
        (:meth:`~scenescore.models.explain.Explanation.doubt`)."""
        scene = self._seen_at(poses)
        if scene is None or self.model.config.absolute or not self.relations:
            return {}
        doubted = [
            n
            for n, v in flagged.items()
            if n in scene.names and any(not f.startswith(CAVEAT) for f in v.flags)
        ]
        return {n: RELATION + explain(self.model, scene, n).doubt() for n in doubted}

    def doubts(self, poses: Tensor) -> Tensor | None:
        """Rows that put a moving object the energy sees where the model's data never had one of its
        category: pinned at a bound none comes near, or farther from the others than any (the trust
        reference's ``bound`` and ``far`` flags); None without a reference or a moving object."""
        ref = self.model.trust
        if ref is None or self.visible_scene is None:
            return None
        moving = self._moving()
        if not moving:
            return None
        x = poses.detach()[:, self.visible].to("cpu", torch.float64).numpy()
        return torch.as_tensor(outside_data(ref, self.visible_scene, moving, x), device=poses.device)

    def propose(self, x: Tensor, generator: torch.Generator) -> Tensor | None:
        """``x (B, N, 3)`` with each moving object the energy sees put at a pose relative to one of the
        scene's known visible objects that its data has (:meth:`TrustReference.anchored`, drawn
        uniformly by ``generator``); None without a reference, a moving object or a known one."""
        ref = self.model.trust
        if ref is None or self.visible_scene is None:
            return None
        scene, mov = self.binding.scene, self.binding.movable
        known = [i for i in self.visible if not mov[i]]
        moving = [i for i in self.visible if mov[i]]
        if not known or not moving:
            return None
        anchors = [scene.objects[i].category for i in known]
        out = x.clone()
        for i in moving:
            idx, rel = ref.anchored(scene.objects[i].category, anchors)
            if not len(idx):
                continue
            u = draw("rand", (x.shape[0],), generator, x.device, torch.float64)
            pick = (u * len(idx)).long().clamp(max=len(idx) - 1)  # (B,) a relation for each row
            at = torch.as_tensor(np.asarray(known)[idx], device=x.device)[pick]
            r = torch.as_tensor(rel, dtype=x.dtype, device=x.device)[pick]
            out[:, i] = compose_poses(x[torch.arange(x.shape[0], device=x.device), at], r)
        return out

    def evaluate(self, poses: Tensor) -> Tensor:
        dtype = self.model.dtype
        if self._fn is None:
            self.binding  # noqa: B018 - raises
        if self._idx is not None:
            poses = poses[:, self._idx]
        x = poses.to(dtype)
        e = None if self._mover is None else self._mover(x)  # None where others than its object move
        return (self._fn(x) if e is None else e).to(poses.dtype)  # type: ignore[misc]


def _energy_casadi(term: LearnedEnergy, weight: float, nlp: SymbolicProblem) -> None:
    """The network rebuilt symbolically (``energy: mx``, exact Hessians) or through torch (``callback``;
    always for a model with a local graph, whose neighbour lists have no symbolic form, and for an
    ensemble)."""
    if nlp.options.get("energy", "mx") != "mx" or term.model.config.local or term.model.members > 1:
        objective_by_torch(term, weight, nlp)
        return
    seen = ca.vertcat(*[nlp.poses[i, :] for i in term.visible])
    nlp.add_objective(weight * energy_mx(term.model, term.visible_scene, seen))


class EnergySpec(CostSpec):
    """``{type: energy, weight, objects: [names the energy sees], name}``; the file's ``model`` key."""

    type: Literal["energy"]
    objects: list[str] | None = None

    def build(self, ctx: SpecContext) -> Cost:
        return LearnedEnergy(ctx.model(()), objects=ctx.objects(self.objects, ("objects",)), **self.named())


register_casadi_form(LearnedEnergy, _energy_casadi)
register_cost_type("energy", EnergySpec)
