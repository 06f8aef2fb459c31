"""A learned relation bound to named objects: ``Relation(model, objects=("cup", "plate"))`` (torch, YAML).

A relation model is an ordinary :class:`~scenescore.models.ScoreModel` trained on small example scenes
of one relation (``scenescore generate relation-left_of``: 2 or 3 objects each, see
:mod:`scenescore.scenarios.relations`). In those scenes each object's role (the subject, the reference,
a third object) is told by its colour, :data:`ROLE_COLOURS`; every other feature (shape, size) varies.
The term shows the model the named objects of a new scene with their own footprints and the colours of
their roles, so that one model binds to any objects: ``Relation(left_of, ("cup", "plate"))`` is low
where the cup stands left of the plate. Several ``instances`` of one model (``[("cup", "plate"),
("fork", "plate")]``) are one term, evaluated in one network call, their energies summed.

It differs from ``LearnedEnergy(model, objects=[...])``, which shows the model the objects as they
look (a scene energy restricted to some objects) and judges them against the model's data as a guide.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Literal

import torch
from torch import Tensor

from ..models import ScoreModel
from ..models.batching import SceneTensors
from ..models.model import with_walls
from ..models.network import round_flags
from ..scene.scene import Scene, SceneObject
from .base import Cost
from .spec import CostSpec, SpecContext, register_cost_type
from .terms import CostError, check_scene_names

__all__ = ["Relation", "RelationSpec", "ROLE_COLOURS", "COMPASS", "as_roles", "compass", "reads_compass"]

#: the colour of each role in a relation's example scenes and in the scene a :class:`Relation` shows
#: its model: subject, reference, third object (``between``: the subject between the other two)
ROLE_COLOURS: tuple[tuple[int, int, int], ...] = ((220, 40, 40), (40, 90, 220), (40, 170, 60))


#: the marker of the world's axes in the example scenes of a relation that depends on them (left of,
#: in front of, aligned along x): the energy network reads poses relative to one another, so without a
#: fixed object of known heading it cannot tell left from right. It stands at the table's centre in the
#: examples; a :class:`Relation` shows it at the centre of its objects, heading 0.
COMPASS = "compass"


def compass(pose: Sequence[float] = (0.0, 0.0, 0.0)) -> SceneObject:
    """The axes marker (:data:`COMPASS`): a small fixed dark box at ``pose``."""
    x, y, t = (float(v) for v in pose)
    return SceneObject(COMPASS, COMPASS, (0.04, 0.02), (x, y, t), color=(20, 20, 20), fixed=True)


def reads_compass(model: ScoreModel) -> bool:
    """Whether ``model`` was trained on examples with the axes marker (its trust reference knows it)."""
    trust = model.trust
    return trust is not None and COMPASS in trust.nearest


def as_roles(objects: Sequence[SceneObject]) -> list[SceneObject]:
    """``objects`` in the colours of their roles (:data:`ROLE_COLOURS`, in order), their footprints kept
    and any precomputed ``features`` or ``image`` dropped (the encoder reads the role from the colour)."""
    if len(objects) > len(ROLE_COLOURS):
        raise CostError(f"Relation: a relation binds at most {len(ROLE_COLOURS)} objects, got {len(objects)}")
    return [replace(o, color=c, features=None, image=None) for o, c in zip(objects, ROLE_COLOURS)]


def _instances(objects: Sequence[str] | Sequence[Sequence[str]]) -> list[tuple[str, ...]]:
    """One tuple of names, or a list of them, as a list of instances of one arity; errors say what is wrong."""
    if isinstance(objects, str) or not isinstance(objects, Sequence) or len(objects) == 0:
        raise CostError(
            f"Relation: objects: expected names such as ('cup', 'plate') or a list of such tuples, got {objects!r}"
        )
    single = all(isinstance(o, str) for o in objects)
    items: Sequence = [objects] if single else objects  # one instance, or a list of them
    rows: list[tuple[str, ...]] = [tuple(o) for o in items]
    for row in rows:
        if not 2 <= len(row) <= len(ROLE_COLOURS) or not all(isinstance(n, str) for n in row):
            raise CostError(
                f"Relation: objects: each instance names 2 to {len(ROLE_COLOURS)} objects, got {row!r}"
            )
        if len(set(row)) != len(row):
            raise CostError(f"Relation: objects: an instance names one object twice: {row!r}")
        if len(row) != len(rows[0]):
            raise CostError(
                f"Relation: objects: every instance of one model names as many objects, got {rows[0]!r} "
                f"and {row!r}"
            )
    return rows


class Relation(Cost):
    """The energy of a relation model for named objects of the scene, summed over its ``instances``.

    ``objects``: the names of the objects in their roles, ``("cup", "plate")`` (for ``left_of``: the cup
    left of the plate), or a list of such tuples, each an instance of the relation (one network call
    for all). The model must read objects with the footprint encoder (the role is read from the colour).
    """

    needs_scene = True

    def __init__(
        self,
        model: ScoreModel,
        objects: Sequence[str] | Sequence[Sequence[str]],
        name: str | None = None,
        frame: bool | None = None,
    ):
        if not hasattr(model, "energy_fn"):
            raise CostError(
                f"Relation: expected a ScoreModel (scenescore.models.load), got {type(model).__name__}"
            )
        if getattr(model.encoder, "name", None) != "footprint":
            raise CostError(
                f"Relation: the model reads objects with the {getattr(model.encoder, 'name', '?')!r} "
                "encoder; a relation model is trained with the 'footprint' encoder, which reads each "
                "object's role from its colour"
            )
        self.model = model
        self.frame = reads_compass(model) if frame is None else bool(frame)
        self.instances = _instances(objects)
        self.name = name or "relation(" + "; ".join(", ".join(r) for r in self.instances) + ")"
        self._idx: Tensor | None = None  # (K, m) scene indices of each instance's objects
        self._st: SceneTensors | None = None  # the K role scenes, encoded
        self._round = False  # whether one of their objects is round (read once, at binding)
        self._nodes: Tensor | None = None  # (K, m, D) their node embeddings

    def model_device(self) -> torch.device:
        """The model's device: a problem with this term runs there unless told otherwise."""
        return self.model.device

    def role_scenes(self) -> list[Scene]:
        """Each instance as the model sees it: its objects alone, in the colours of their roles."""
        scene = self.binding.scene
        extra = [compass()] if self.frame else []
        return [
            Scene([*as_roles([scene[n] for n in row]), *extra], scene.bounds, meta=scene.meta)
            for row in self.instances
        ]

    def _on_bind(self) -> None:
        b = self.binding
        if b.device != self.model.device:
            raise CostError(
                f"Relation {self.name!r}: the model is on {self.model.device}, the problem on {b.device}; "
                "load the model there (models.load(path, device=...)) or move it (model.to(device))"
            )
        idx = [
            check_scene_names(b.scene, list(row), f"Relation {self.name!r}: objects")
            for row in self.instances
        ]
        self._idx = torch.tensor(idx, dtype=torch.long, device=b.device)
        with torch.no_grad():
            self._st = self.model.tensors(self.role_scenes())
            self._nodes = self.model.net.node_embedding(self._st.feats, self._st.sizes)
            self._round = round_flags(self.model.config, self._st.round) is not None

    def evaluate(self, poses: Tensor) -> Tensor:
        """``sum_k E_k(poses of instance k)``: the K instances' poses stacked on the batch, one call."""
        if self._idx is None or self._st is None:
            self.binding  # noqa: B018 - raises
        idx, st, nodes = self._idx, self._st, self._nodes
        assert idx is not None and st is not None and nodes is not None
        b, (k, m) = poses.shape[0], idx.shape
        x = poses.to(self.model.dtype)[:, idx]  # (B, K, m, 3)
        x = x.transpose(0, 1).reshape(k * b, m, 3)  # instance-major rows
        if self.frame:  # the axes marker at the centre of the instance's objects, heading 0
            centre = x[:, :, :2].mean(1, keepdim=True)
            x = torch.cat([x, torch.cat([centre, torch.zeros_like(centre[..., :1])], -1)], 1)
        rows = torch.arange(k, device=poses.device).repeat_interleave(b)
        sk = st.index(rows)
        e = self.model.net(
            with_walls(x, sk),
            None,
            None,
            sk.mask,
            nodes=nodes[rows],
            round=sk.round if self._round else None,
            weight_grads=False,
        )
        return e.reshape(k, b).sum(0).to(poses.dtype)


class RelationSpec(CostSpec):
    """``{type: relation, model: left_of.ckpt, objects: [cup, plate] or [[cup, plate], ...], weight, name}``.

    ``model``: a checkpoint path, relative to the problem file; one loaded model serves every term
    naming that file. The default name is the checkpoint's stem and the objects: ``left_of(cup, plate)``.
    """

    type: Literal["relation"]
    model: str
    objects: list[str] | list[list[str]]

    def build(self, ctx: SpecContext) -> Cost:
        single = all(isinstance(o, str) for o in self.objects)
        try:
            rows = _instances(self.objects)
        except CostError as e:
            raise CostError(f"objects: {str(e).removeprefix('Relation: objects: ')}") from None
        for k, row in enumerate(rows):
            ctx.objects(list(row), ("objects",) if single else ("objects", k))
        model = ctx.checkpoint(self.model, ("model",))
        named = "; ".join(", ".join(r) for r in rows)
        return Relation(model, objects=rows, name=self.name or f"{Path(self.model).stem}({named})")


register_cost_type("relation", RelationSpec)
