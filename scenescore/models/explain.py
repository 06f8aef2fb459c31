"""Why an object stands where it does: its learned energy broken into the relations that hold it there.

The object's well is how much the energy rises when the object alone moves away: the mean rise over
:data:`DIRECTIONS` displacements on each of the rings :data:`RINGS` (in length scales), its heading
kept. The poses act on the energy only through the edges the message layers read, so along each
displacement's straight path the rise is the sum, over the edges between the object and each other
node, of the gradient with respect to the edge times the edge's change (integrated gradients,
:data:`STEPS` trapezoids in float64; an ensemble's parts are its members' mean). A neighbour's part is
that of its two edges: positive, the neighbour holds the object where it is; negative, it pushes the
object off; the parts, the walls' and a small rest add up to the depth. Each relation is said as the
object's place in the neighbour's frame (a round neighbour, which has no heading, by the distance
alone), and beside it how many of the example pairs of the two categories that the model saw (its trust
reference's relations) stand within :data:`MATCH` length scales of it, or, given the example scenes,
which of them show it.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch

from ..geometry.poses import relative_poses
from ..scene.scene import Scene, wrap_angle
from ..scene.units import length_unit
from .ensemble import members_of
from .model import with_walls
from .network import round_flags

__all__ = ["DIRECTIONS", "MATCH", "RINGS", "Explanation", "Relation", "explain", "well_depth"]

RINGS = (0.5, 1.0, 2.0)  # length scales the object is displaced by
DIRECTIONS = 8  # displacements per ring, evenly round it
MATCH = 0.5  # length scales within which an example pair shows the same relation
NEIGHBOURS = 8  # the relations listed, the largest parts first
STEPS = 16  # trapezoids along each displacement's path


@dataclass(frozen=True)
class Relation:
    """One neighbour's part in holding an object: ``part`` (energy units) and its ``share`` of the well,
    where the object stands from it (``offset``: x, y in the neighbour's frame, in the scene's unit, and
    the relative heading), ``said`` in words, and the examples that show it: ``shown`` of the ``pairs``
    example pairs of the two categories the model saw, and ``scenes``, the indices of the example scenes
    showing it when they were given (else None)."""

    neighbour: str
    category: str
    part: float
    share: float
    offset: tuple[float, float, float]
    said: str
    shown: int
    pairs: int
    scenes: list[int] | None = None

    @property
    def examples(self) -> str:
        """How the examples bear the relation out, in words."""
        if self.scenes is not None:
            if not self.scenes:
                return "no example scene"
            k = len(self.scenes)
            return f"{k} example scene{'s' if k > 1 else ''} ({', '.join(map(str, self.scenes[:6]))}" + (
                ", ...)" if k > 6 else ")"
            )
        if not self.pairs:
            return "no example pair of these categories"
        return f"{self.shown} of {self.pairs} example pairs"


@dataclass(frozen=True)
class Explanation:
    """What holds ``name`` (of ``category``) at ``pose``: the well's ``depth`` (energy units) and its
    parts: the listed neighbours' :class:`Relation`, the largest part first; ``others``, the parts of the
    objects not listed; ``walls``, the bounds' sides' (a model that sees them, else None); ``rest``, what
    the integration leaves (near zero: the parts add up to the depth; in a local graph also what its
    neighbour lists changing along the paths add, where the lists cut off edges of weight). Lengths in ``unit``; ``rings``:
    the displacements' radii (in it)."""

    name: str
    category: str
    pose: tuple[float, float, float]
    depth: float
    relations: list[Relation]
    others: float
    unlisted: int
    walls: float | None
    rest: float
    unit: str
    rings: tuple[float, ...] = field(default=())

    @property
    def strongest(self) -> Relation | None:
        """The relation that holds the object most, or None when no neighbour holds it."""
        held = [r for r in self.relations if r.part > 0]
        return held[0] if held else None

    def doubt(self) -> str:
        """The relation to doubt when the placement is flagged: the strongest hold no example shows
        (among the three strongest), else the strongest, with how the examples bear it out."""
        held = [r for r in self.relations if r.part > 0][:3]
        if not held:
            return "no neighbour holds it there"
        r = next((r for r in held if r.shown == 0 and not r.scenes), held[0])
        return (
            f"its place rests most on standing {r.said} (part {r.part:.3g} of the well's {self.depth:.3g}), "
            f"shown by {r.examples}"
        )

    def table(self) -> str:
        """The explanation as text: the well, then one row per relation, the other parts and the rest."""
        x, y, h = self.pose
        rings = ", ".join(f"{r:.3g}" for r in self.rings)
        lines = [
            f"{self.name} ({self.category}) at ({x:.4g}, {y:.4g}, {math.degrees(h):.0f} deg): well depth "
            f"{self.depth:.3g} (the energy's mean rise with it moved {rings} {self.unit} away)"
        ]
        w = max([len("neighbour"), len("the walls")] + [len(r.neighbour) for r in self.relations])
        c = max([len("category")] + [len(r.category) for r in self.relations])
        lines.append(f"{'neighbour':<{w}}  {'category':<{c}}  {'part':>8}  {'share':>6}  where; shown by")
        for r in self.relations:
            share = f"{r.share:>6.0%}" if self.depth > 0 else f"{'-':>6}"
            lines.append(
                f"{r.neighbour:<{w}}  {r.category:<{c}}  {r.part:>8.3g}  {share}  {r.said}; {r.examples}"
            )
        extra = [(f"{self.unlisted} others", self.others)] * bool(self.unlisted) + (
            [("the walls", self.walls)] if self.walls is not None else []
        )
        for label, v in extra + [("rest", self.rest)]:
            share = f"{v / self.depth:>6.0%}" if self.depth > 0 else f"{'-':>6}"
            lines.append(f"{label:<{w}}  {'':<{c}}  {v:>8.3g}  {share}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _offsets(length: float) -> np.ndarray:
    """The displacements ``(M, 2)``: :data:`DIRECTIONS` per ring of :data:`RINGS` length scales."""
    a = 2 * math.pi * np.arange(DIRECTIONS) / DIRECTIONS
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)
    return np.concatenate([ring * r * length for r in RINGS])


def well_depth(model: Any, scene: Scene, name: str, offsets: np.ndarray) -> float:
    """The mean rise of ``scene``'s energy (every pose known) when ``name`` alone moves by each row of
    ``offsets (M, 2)``, by the model as it places (its own precision)."""
    i = scene.index(name)
    p = np.repeat(scene.poses()[None], 1 + len(offsets), axis=0)
    p[1:, i, :2] += offsets
    with torch.no_grad():
        st = model.tensors([scene])
        x = with_walls(torch.as_tensor(p, dtype=model.dtype, device=model.device), st)
        e = model.energy(x, st, weight_grads=False).double().cpu().numpy()
    return float(np.mean(e[1:] - e[0]))


def _attribution(model: Any, scene: Scene, i: int, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Object ``i`` of ``scene`` moved along each row of ``offsets (M, 2)``: the energy's rise ``(M,)``
    and the part in it of the two edges between ``i`` and each node ``(M, N')`` (N': with the model's
    walls), by integrated gradients through the edges (:data:`STEPS` trapezoids per path; the mean of
    an ensemble's members)."""
    m, k = len(offsets), STEPS + 1
    t = np.linspace(0.0, 1.0, k)
    p = np.repeat(scene.poses()[None, None], m, axis=0).repeat(k, axis=1)  # (M, K, N, 3)
    p[:, :, i, :2] += offsets[:, None, :] * t[None, :, None]
    st = model.tensors([scene]).to("cpu")
    x = with_walls(torch.as_tensor(p.reshape(m * k, *p.shape[2:]), dtype=torch.float64), st)
    x.requires_grad_(True)
    nets = members_of(model.net)
    got = [_member_parts(copy.deepcopy(net).double().cpu(), x, st, i, (m, k)) for net in nets]
    return np.mean([g[0] for g in got], axis=0), np.mean([g[1] for g in got], axis=0)


def _member_parts(
    net: Any, x: torch.Tensor, st: Any, i: int, paths: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_attribution` by one float64 network ``net`` at the poses ``x (M K, N', 3)`` of ``paths =
    (M, K)``: M paths of K points."""
    b = x.shape[0]
    seen: dict[str, Any] = {}

    def tap(e: torch.Tensor, pair: torch.Tensor, index: torch.Tensor | None) -> None:
        for v in (e, pair):
            if v.requires_grad:  # a dense graph's weights do not depend on the poses
                v.retain_grad()
        seen.update(e=e, pair=pair, index=index)

    feats, sizes = st.feats.double().expand(b, -1, -1), st.sizes.double().expand(b, -1, -1)
    mask, rnd = st.mask.expand(b, -1), round_flags(net.cfg, st.round)
    with torch.enable_grad():
        energy = net.readout(net.pooled(*net.resolve(x, feats, sizes, mask, None, rnd), tap=tap))
        energy.sum().backward()
    e, pair, index = seen["e"], seen["pair"], seen["index"]
    parts = _trapezoids(*_touching(e.detach(), e.grad, index, i), *paths).sum(-1)
    if pair.grad is not None:
        parts = parts + _trapezoids(*_touching(pair.detach(), pair.grad, index, i), *paths)
    en = energy.detach().reshape(paths).numpy()
    return en[:, -1] - en[:, 0], parts.sum(dim=(1, 3)).numpy()


def _touching(
    v: torch.Tensor, g: torch.Tensor, index: torch.Tensor | None, i: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """The values ``v`` and gradients ``g`` (``(B, N, N or S, ...)``, receiver by sender or slot) of the
    edges between node ``i`` and each node ``j``, into ``i`` and out of it stacked: ``(B, N, 2, ...)``,
    zero where the graph has no such edge. A local graph's slots are read by their senders at each
    point, so that an edge is followed however its receiver's neighbour list reorders."""
    if index is None:
        return torch.stack([v[:, i], v[:, :, i]], dim=2), torch.stack([g[:, i], g[:, :, i]], dim=2)
    b, n = v.shape[:2]
    extra = v.shape[3:]
    into = index[:, i]  # (B, S) senders of i's slots
    out_mask = (index == i).to(v.dtype).reshape(b, n, -1, *([1] * len(extra)))

    def dense(t: torch.Tensor) -> torch.Tensor:
        inward = torch.zeros(b, n, *extra, dtype=t.dtype)
        slots = into.reshape(b, -1, *([1] * len(extra))).expand(-1, -1, *extra)
        inward.scatter_add_(1, slots, t[:, i])
        return torch.stack([inward, (t * out_mask).sum(2)], dim=2)

    return dense(v), dense(g)


def _trapezoids(v: torch.Tensor, g: torch.Tensor, m: int, k: int) -> torch.Tensor:
    """Each step's ``0.5 (g_t + g_t+1) (v_t+1 - v_t)`` of ``v, g (M K, ...)`` along ``M`` paths of ``K``
    points: ``(M, K - 1, ...)``."""
    v, g = v.reshape(m, k, *v.shape[1:]), g.reshape(m, k, *g.shape[1:])
    return 0.5 * (g[:, 1:] + g[:, :-1]) * (v[:, 1:] - v[:, :-1])


def _in_frames(p: np.ndarray) -> np.ndarray:
    """Every pose of ``p (N, 3)`` in every other's frame: ``(anchor, object, 3)``, the heading wrapped
    to [-pi, pi)."""
    t = torch.as_tensor(p, dtype=torch.float64)
    rel = relative_poses(t[:, None], t[None, :])
    rel[..., 2] = wrap_angle(rel[..., 2])
    return rel.numpy()


def _said(scene: Scene, i: int, j: int, unit: str) -> tuple[tuple[float, float, float], str]:
    """Where object ``i`` stands in object ``j``'s frame, and in words."""
    x, y, h = (float(v) for v in _in_frames(scene.poses()[[j, i]])[0, 1])
    dist = math.hypot(x, y)
    name = scene.objects[j].name
    if scene.objects[j].round:
        return (x, y, h), f"{dist:.3g} {unit} from {name}"
    side = ("+x" if x > 0 else "-x") if abs(x) >= abs(y) else ("+y" if y > 0 else "-y")
    return (x, y, h), f"{dist:.3g} {unit} on {name}'s {side} side"


def _close(a: np.ndarray, b: np.ndarray, round_anchor: bool, tol: float) -> np.ndarray:
    """Which rows of ``a (K, 2)`` stand within ``tol`` of ``b (2,)`` (a round anchor: by distance)."""
    if round_anchor:
        return np.abs(np.linalg.norm(a, axis=1) - np.linalg.norm(b)) <= tol
    return np.linalg.norm(a - b, axis=1) <= tol


def _shown_in_scenes(
    scenes: Sequence[Scene], cat: str, anchor: str, rel: np.ndarray, round_anchor: bool, tol: float
) -> list[int]:
    """The indices of ``scenes`` holding an object of ``cat`` within ``tol`` of ``rel (2,)`` in the frame
    of an object of ``anchor``."""

    def shows(s: Scene) -> bool:
        cats = np.array([o.category for o in s.objects])
        anchors, objs = np.flatnonzero(cats == anchor), np.flatnonzero(cats == cat)
        if not len(anchors) or not len(objs):
            return False
        frames = _in_frames(s.poses())
        pairs = [(a, o) for a in anchors for o in objs if a != o]
        return bool(pairs) and bool(
            _close(np.array([frames[a, o, :2] for a, o in pairs]), rel, round_anchor, tol).any()
        )

    return [k for k, s in enumerate(scenes) if shows(s)]


def _relation(
    model: Any, scene: Scene, i: int, j: int, part: float, depth: float, scenes: Sequence[Scene] | None
) -> Relation:
    unit = length_unit(scene)
    length = float(model.config.length_scale)
    offset, said = _said(scene, i, j, unit)
    cat, anchor = scene.objects[i].category, scene.objects[j].category
    round_anchor = scene.objects[j].round
    ref = model.trust
    rows = np.asarray(((ref.relations or {}).get(cat, {}).get(anchor, [])) if ref is not None else [])
    rel = np.asarray(offset[:2]) / length
    shown = int(_close(rows[:, :2], rel, round_anchor, MATCH).sum()) if len(rows) else 0
    found = None
    if scenes is not None:
        found = _shown_in_scenes(scenes, cat, anchor, np.asarray(offset[:2]), round_anchor, MATCH * length)
    share = part / depth if depth > 0 else 0.0
    return Relation(scene.objects[j].name, anchor, part, share, offset, said, shown, len(rows), found)


def explain(
    model: Any,
    scene: Scene,
    name: str,
    scenes: Sequence[Scene] | None = None,
    neighbours: int = NEIGHBOURS,
) -> Explanation:
    """What holds ``name`` of ``scene`` (every pose known) where it stands, by ``model``'s energy: the
    well's depth and the relations of the ``neighbours`` objects with the largest parts in it (see the
    module's description), the others' summed. ``scenes``: the example scenes, to name the ones
    showing each relation."""
    if name not in scene.names:
        raise KeyError(f"explain: no object {name!r} in the scene (it has {', '.join(scene.names)})")
    if scene.unknown:
        raise ValueError(f"explain: every pose must be known; place {', '.join(scene.unknown)} first")
    if neighbours < 1:
        raise ValueError(f"explain: neighbours: expected 1 or more, got {neighbours}")
    if model.config.absolute:
        raise ValueError("explain: the model reads absolute poses (the Abs ablation), not relations")
    i = scene.index(name)
    length = float(model.config.length_scale)
    rise, parts = _attribution(model, scene, i, _offsets(length))
    pair = parts.mean(axis=0)  # (N'): both edges between the object and each node
    depth, held = float(rise.mean()), pair[: len(scene)]
    order = [int(j) for j in np.argsort(-np.abs(held), kind="stable") if j != i][:neighbours]
    rels = sorted(
        (_relation(model, scene, i, j, float(held[j]), depth, scenes) for j in order), key=lambda r: -r.part
    )
    p = scene.poses()
    return Explanation(
        name=name,
        category=scene.objects[i].category,
        pose=(float(p[i, 0]), float(p[i, 1]), float(p[i, 2])),
        depth=depth,
        relations=rels,
        others=float(held.sum() - held[i] - sum(r.part for r in rels)),
        unlisted=len(scene) - 1 - len(rels),
        walls=float(pair[len(scene) :].sum()) if model.config.walls else None,
        rest=float(depth - pair.sum() + pair[i]),  # pair[i]: its self-edge, which no path changes
        unit=length_unit(scene),
        rings=tuple(r * length for r in RINGS),
    )
