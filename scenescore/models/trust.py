"""How far to trust a placement: its energy against the examples', and checks a person would make.

Training stores a :class:`TrustReference` in the checkpoint: each object's share of the energy of the
reference scenes (held-out ones when there are any, else the training scenes; :func:`energy_shares`),
their per-object energies ``E / N``, and what the data's geometry looks like in its own length scale
(how far each category lies from its nearest neighbour and from the nearest object of each other
category, how near each category comes to the bounds, which feature vectors occur;
:mod:`scenescore.models.layout`). :func:`assess` gives every placed object a confidence (the fraction of its
category's reference shares at or above its own) and flags it,
with the reason, when

- the object's share of the energy (the scene's energy minus the scene's without it) lies beyond that of
  every object of its category in the reference scenes, by more than :data:`SHARE_MARGIN` times their
  interquartile range (``energy``; in checkpoints from before those
  shares were stored: the placed scene's energy per object beyond the reference scenes'),
- for an ensemble (:mod:`scenescore.models.ensemble`): most members (:func:`members_needed`) put the
  object's share beyond that of every object of its category in the reference scenes by that member,
  by more than :data:`MEMBER_MARGIN` times their interquartile range (``members``; the confidence is
  the lowest member's whether or not the flag fires),
- the object is farther from every other object than any object of its category in the data (``far``),
  or farther from every object of some category (``apart``: a chair from every table;
  :func:`~scenescore.models.layout.apart_limits`),
- it is pinned at a bound that no object of its category comes near in the data (within
  :data:`NEAR_BOUND` length scales: ``bound``),
- its category's features are far from every feature seen in training (``novel``),
- the model's held-out evaluation found it unlearned: a held-out loss not below chance (not when one
  scene was left out at a time), or the object's category placed no better than nearest neighbour
  (``validation``; the model's ``info.caveats``).

A sampling solver's result adds one more (:mod:`scenescore.models.rivals`): another particle puts the
object far away for nearly the same cost (``rival``). A flagged object's flags end with the relation
the learned energy holds it by that the examples bear out least (``relation``;
:meth:`~scenescore.models.explain.Explanation.doubt`), and a placement of a category the examples
leave free carries a note saying so (:mod:`scenescore.models.freedom`).

It also keeps where the training data puts each category relative to each other one
(:func:`relations`), from which placement draws candidate poses beside the scene's known objects
(:meth:`TrustReference.anchored`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch

from ..scene.scene import Scene
from .freedom import BOUNDS, Spread, spreads
from .layout import (
    BOUND_TOL,
    OVERLAP_TOL,
    apart_limits,
    bound_gap,
    bounds_touched,
    evenly,
    nearest_distances,
    overlapping_categories,
    relations,
)
from .shares import energy_per_object, energy_shares, member_shares, shares_by_energy

__all__ = [
    "TrustReference",
    "Assessment",
    "reference",
    "members_doubt",
    "members_needed",
    "NEAR_BOUND",
    "outside_data",
    "apart_distances",
    "energy_per_object",
    "energy_shares",
    "member_shares",
    "CAVEAT",
    "RELATION",
    "SHARE_MARGIN",
    "MEMBER_MARGIN",
    "limit_beyond",
]

# length scales: a category whose data come this close to a bound may be pinned there (a nightstand
# against a bedroom's wall may stand against it; a coffee table far from every wall may not)
NEAR_BOUND = 0.5
FAR_FACTOR = 1.5  # flag an object this many times farther from its neighbours than the data's farthest
MAX_FEATURES = 256  # distinct feature vectors kept in a checkpoint
POOLED_RELATIONS = 256  # relative poses an object of an unseen category draws from (any category's)
MAX_SHARES = 256  # energy shares kept per category (evenly spaced order statistics, the extremes kept)
# interquartile ranges of the reference beyond its largest value at which a flag fires: the energy
# share's, an ensemble member's share (lower: the members' doubt is the catastrophic placement's sign),
# the energy per object of a checkpoint without shares (docs/studies.md, "The share flags' margins")
SHARE_MARGIN = 1.0
MEMBER_MARGIN = 0.5
ENERGY_MARGIN = 0.5
CAVEAT = "validation: "  # how a flag from the model's held-out evaluation begins (not out of distribution)
# how the line naming the relation a flagged placement doubts begins: a note beside the flags, no flag
RELATION = "relation: "


@dataclass
class TrustReference:
    """The data a placement is judged against (stored in a checkpoint's ``info["trust"]``)."""

    energies: list[float]  # per-object energies E / N of the reference scenes, sorted
    length_scale: float
    nearest: dict[str, float]  # category -> largest nearest-neighbour distance in the data (length scales)
    nearest_any: float
    touches_bounds: list[str]  # categories with an object touching the bounds in the data
    features: list[list[float]] = field(default_factory=list)  # distinct feature vectors seen in training
    feature_radius: float = 1.0  # an object farther than this from every training feature is novel
    # category pairs whose footprints overlap somewhere in the data (a lamp on a nightstand): placement's
    # non-overlap leaves them be; None in checkpoints from before it was stored (then no pair is exempt)
    overlaps: list[list[str]] | None = None
    # category -> anchor category -> poses [x, y, heading] of the category's training objects in the
    # frame of the anchor's (x, y in length scales): :func:`relations`; None in older checkpoints
    relations: dict[str, dict[str, list[list[float]]]] | None = None
    # category -> the smallest gap between its footprint and a bound in the data (length scales); None in
    # older checkpoints (then only the categories of ``touches_bounds`` may be pinned at a bound)
    bound_gaps: dict[str, float] | None = None
    # category -> each reference object's share of its scene's energy (:func:`energy_shares`), sorted;
    # None in older checkpoints (then ``energy`` judges the placed scene's energy per object)
    shares: dict[str, list[float]] | None = None
    # an ensemble's: each member's ``shares`` (by its own energy); None for one network
    member_shares: list[dict[str, list[float]]] | None = None
    # category -> other category -> the farthest any object of the category stands from the nearest object
    # of the other in a scene holding both (length scales; :func:`apart_limits`); None in older checkpoints
    apart: dict[str, dict[str, float]] | None = None
    # category -> how far the examples disagree on its place at best (length scales; None: one scene
    # shows it) and the anchor they agree best by (:mod:`~scenescore.models.freedom`); None in older
    # checkpoints
    spreads: dict[str, float | None] | None = None
    spread_anchors: dict[str, str] | None = None

    def spread(self, category: str) -> Spread | None:
        """How well the examples pin ``category`` down (:class:`~scenescore.models.freedom.Spread`),
        or None for an unseen category or an older checkpoint."""
        if self.spreads is None or category not in self.spreads:
            return None
        v = self.spreads[category]
        return Spread(math.inf if v is None else v, (self.spread_anchors or {}).get(category, BOUNDS))

    def may_touch_bounds(self, category: str) -> bool:
        """Whether an object of ``category`` pinned at a bound is where the data has them: some object of
        its category comes within :data:`NEAR_BOUND` length scales of a bound (unseen categories never)."""
        if self.bound_gaps is None:
            return category in self.touches_bounds
        return self.bound_gaps.get(category, math.inf) <= NEAR_BOUND

    def bound_reason(self, category: str, unit: str = "m") -> str:
        """Why a pinned object of ``category`` is outside the data, for :func:`assess`'s ``bound`` flag
        (``unit``: how its lengths are said, :func:`length_unit`)."""
        gap = None if self.bound_gaps is None else self.bound_gaps.get(category)
        if gap is None:
            return f"which no {category} in the data touches"
        return f"where no {category} in the data comes within {gap * self.length_scale:.3g} {unit} of a bound"

    def anchored(self, category: str, anchors: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """Where the data would put an object of ``category`` beside objects of the categories
        ``anchors``: ``(idx (K,), rel (K, 3))``, each row a pose relative to ``anchors[idx]`` (metres,
        radians). An unseen category, or one whose anchors' categories the data never pairs it with,
        draws from every category's relations (at most :data:`POOLED_RELATIONS`), beside any anchor
        whose category the data knows, else beside any anchor. Empty without relations or anchors."""
        table = self.relations or {}
        own = table.get(category, {})
        if not any(a in own for a in anchors):
            own = {}
            for by_anchor in table.values():
                for a, rows in by_anchor.items():
                    own.setdefault(a, []).extend(rows)
            own = {a: evenly(rows, POOLED_RELATIONS) for a, rows in sorted(own.items())}
            if own and not any(a in own for a in anchors):
                rows = evenly([r for a in sorted(own) for r in own[a]], POOLED_RELATIONS)
                own = {a: rows for a in anchors}
        idx = [j for j, a in enumerate(anchors) for _ in own.get(a, [])]
        rel = [r for a in anchors for r in own.get(a, [])]
        if not rel:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
        out = np.asarray(rel, dtype=np.float64)
        out[:, :2] *= self.length_scale
        return np.asarray(idx, dtype=np.int64), out

    def may_overlap(self, a: str, b: str) -> bool:
        """Whether objects of categories ``a`` and ``b`` overlap somewhere in the data."""
        return self.overlaps is not None and sorted((a, b)) in self.overlaps

    @property
    def energy_limit(self) -> float:
        """Energies above this lie beyond the reference: its largest plus :data:`ENERGY_MARGIN` times its
        interquartile range."""
        return limit_beyond(np.asarray(self.energies), ENERGY_MARGIN)

    def category_shares(self, category: str, member: int | None = None) -> np.ndarray:
        """The reference shares an object of ``category`` is judged against: its own category's, every
        category's for an unseen one; ``member``: by that member's energy (an ensemble's)."""
        table = (self.shares if member is None else (self.member_shares or [])[member]) or {}
        rows = table.get(category) or [v for vs in table.values() for v in vs]
        return np.sort(np.asarray(rows, dtype=np.float64))

    def share_limit(self, category: str) -> float:
        """Shares above this lie beyond the reference's: its largest plus :data:`SHARE_MARGIN` times its
        interquartile range."""
        return limit_beyond(self.category_shares(category), SHARE_MARGIN)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrustReference:
        """Read a stored reference; a missing, unknown or mistyped field raises ``ValueError`` naming it."""
        if not isinstance(d, dict):
            raise ValueError(f"expected a mapping, got {type(d).__name__}")
        try:
            ref = cls(**d)
        except TypeError as e:
            raise ValueError(str(e).replace("TrustReference.__init__() ", "")) from None

        def finite(v: Any) -> bool:
            return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

        def share_table(t: Any) -> bool:
            return isinstance(t, dict) and all(
                isinstance(v, list) and len(v) > 0 and all(map(finite, v)) for v in t.values()
            )

        checks = {
            "energies": isinstance(ref.energies, list)
            and len(ref.energies) > 0
            and all(map(finite, ref.energies)),
            "length_scale": finite(ref.length_scale) and ref.length_scale > 0,
            "nearest": isinstance(ref.nearest, dict) and all(map(finite, ref.nearest.values())),
            "nearest_any": finite(ref.nearest_any),
            "touches_bounds": isinstance(ref.touches_bounds, list),
            "features": isinstance(ref.features, list)
            and all(isinstance(f, list) and all(map(finite, f)) for f in ref.features),
            "feature_radius": finite(ref.feature_radius),
            "overlaps": ref.overlaps is None or isinstance(ref.overlaps, list),
            "bound_gaps": ref.bound_gaps is None
            or (isinstance(ref.bound_gaps, dict) and all(map(finite, ref.bound_gaps.values()))),
            "shares": ref.shares is None or share_table(ref.shares),
            "apart": ref.apart is None
            or (
                isinstance(ref.apart, dict)
                and all(isinstance(t, dict) and all(map(finite, t.values())) for t in ref.apart.values())
            ),
            "spreads": ref.spreads is None
            or (isinstance(ref.spreads, dict) and all(v is None or finite(v) for v in ref.spreads.values())),
            "spread_anchors": ref.spread_anchors is None
            or (
                isinstance(ref.spread_anchors, dict)
                and all(isinstance(v, str) for v in ref.spread_anchors.values())
            ),
            "member_shares": ref.member_shares is None
            or (isinstance(ref.member_shares, list) and all(map(share_table, ref.member_shares))),
            "relations": ref.relations is None
            or (
                isinstance(ref.relations, dict)
                and all(
                    isinstance(by_anchor, dict)
                    and all(
                        isinstance(rows, list)
                        and all(isinstance(r, list) and len(r) == 3 and all(map(finite, r)) for r in rows)
                        for rows in by_anchor.values()
                    )
                    for by_anchor in ref.relations.values()
                )
            ),
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(
                f"{bad[0]}: not the expected finite numbers or lists, got {getattr(ref, bad[0])!r:.80}"
            )
        return ref


def members_needed(members: int) -> int:
    """How many of an ensemble's ``members`` must doubt a placement (put its share beyond their own
    reference) for the ``members`` flag: most of them. One member's doubt alone, where the others see
    nothing wrong, marks good placements as often as catastrophic ones (docs/studies.md, "How many
    members must doubt")."""
    return members // 2 + 1


def members_doubt(ref: TrustReference, category: str, shares: np.ndarray) -> tuple[float, int]:
    """An object's shares by each member of an ensemble ``(members,)`` against each member's reference:
    the lowest member's confidence, and how many members put it beyond their reference's shares."""
    refs = [ref.category_shares(category, m) for m in range(len(shares))]
    confidence = min(float(np.mean(r >= v)) for r, v in zip(refs, shares))
    return confidence, sum(int(v > limit_beyond(r, MEMBER_MARGIN)) for r, v in zip(refs, shares))


def limit_beyond(values: np.ndarray, margin: float) -> float:
    """The reference's largest value plus ``margin`` times its interquartile range."""
    q25, q75 = np.percentile(values, [25, 75])
    return float(values.max() + margin * (q75 - q25))


@dataclass
class Assessment:
    """One placed object's confidence in [0, 1] and the reasons it is flagged (none: in distribution)."""

    confidence: float
    flags: list[str] = field(default_factory=list)
    # what to know that is no reason to doubt the pose: the examples leave the object's category free
    notes: list[str] = field(default_factory=list)

    @property
    def flagged(self) -> bool:
        return bool(self.flags)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"confidence": round(self.confidence, 4), "flags": list(self.flags)}
        return {**out, "notes": list(self.notes)} if self.notes else out


def apart_distances(
    ref: TrustReference, scene: Scene, i: int, poses: np.ndarray
) -> list[tuple[str, np.ndarray, float]]:
    """Object ``i`` of ``scene`` at each row of ``poses (B, N, 3)``: ``(category, distance (B,), limit)``
    for each category of :attr:`TrustReference.apart` beside its own that the scene holds, the distance
    to the nearest object of it and the data's farthest, in metres."""
    table = (ref.apart or {}).get(scene.objects[i].category, {})
    cats = np.array([o.category for o in scene.objects])
    out = []
    for c, limit in sorted(table.items()):
        others = [j for j in np.flatnonzero(cats == c).tolist() if j != i]
        if others and limit > 0:
            d = np.linalg.norm(poses[:, others, :2] - poses[:, i : i + 1, :2], axis=-1).min(axis=1)
            out.append((c, d, limit * ref.length_scale))
    return out


def outside_data(ref: TrustReference, scene: Scene, names: Sequence[str], poses: np.ndarray) -> np.ndarray:
    """Rows of ``poses (B, N, 3)`` that put an object of ``names`` where the data never had one of its
    category: pinned at a bound that none comes near, farther from every other object than any, or farther
    from every object of some category than any (:func:`assess`'s ``bound``, ``far`` and ``apart`` flags,
    for a whole population): ``(B,)`` bool."""
    out = np.zeros(len(poses), dtype=bool)
    tol = BOUND_TOL * ref.length_scale
    for name in names:
        i = scene.index(name)
        o = scene.objects[i]
        if not ref.may_touch_bounds(o.category):
            out |= bounds_touched(o, poses[:, i], scene.bounds, tol)[1].any(axis=1)
        far = ref.nearest.get(o.category, ref.nearest_any)
        if far > 0 and len(scene) > 1:
            d = np.linalg.norm(np.delete(poses[:, :, :2], i, axis=1) - poses[:, i : i + 1, :2], axis=-1)
            out |= d.min(axis=1) / ref.length_scale > FAR_FACTOR * far
        for _, d, limit in apart_distances(ref, scene, i, poses):
            out |= d > FAR_FACTOR * limit
    return out


def reference(
    model: Any, train: Sequence[Scene], held_out: Sequence[Scene] = (), feature_noise: float = 0.0
) -> TrustReference:
    """The trust reference of a trained model: energies of ``held_out`` (else ``train``), geometry and
    features of everything it saw. ``feature_noise``: the std of the noise training added to every
    feature; the network has seen features that far from the data's (about ``std * sqrt(dim)``), and
    an object is novel 1.5 times farther than that (at least 1)."""
    scenes = list(train) + list(held_out)
    length = float(model.config.length_scale)
    nearest: dict[str, float] = {}
    gaps: dict[str, float] = {}  # category -> its smallest gap to a bound in the data (metres)
    for s in scenes:
        p = s.poses()
        nn = nearest_distances(p) / length
        for o, d, pose in zip(s.objects, nn, p):
            if math.isfinite(d):
                nearest[o.category] = max(nearest.get(o.category, 0.0), float(d))
            gaps[o.category] = min(gaps.get(o.category, math.inf), bound_gap(o, pose, s.bounds))
    with torch.no_grad():
        feats = torch.cat([model.tensors([s]).feats[0] for s in train]).double().cpu().numpy()
    uniq = np.unique(np.round(feats, 4), axis=0)[: max(8, min(MAX_FEATURES, 20_000 // feats.shape[1]))]
    radius = max(1.0, 1.5 * feature_noise * math.sqrt(feats.shape[1]))
    size = getattr(model, "members", 1)
    tables: list[dict[str, list[float]]] = [{} for _ in range(size + 1 if size > 1 else 1)]
    for s in held_out or train:  # the mean energy's shares, then each member's
        for table, row in zip(tables, shares_by_energy(model, s, None, members=True), strict=True):
            for o, v in zip(s.objects, row):
                table.setdefault(o.category, []).append(float(v))
    kept = [{c: evenly(sorted(v), MAX_SHARES) for c, v in sorted(t.items())} for t in tables]
    pinned = spreads(scenes, length)
    return TrustReference(
        energies=sorted(energy_per_object(model, held_out or train)),
        length_scale=length,
        nearest=nearest,
        nearest_any=max(nearest.values(), default=0.0),
        touches_bounds=sorted(c for c, g in gaps.items() if g <= BOUND_TOL * length),
        features=uniq.tolist(),
        feature_radius=radius,
        overlaps=overlapping_categories(scenes, OVERLAP_TOL * length),
        relations=relations(train, length),
        bound_gaps={c: max(0.0, g) / length for c, g in gaps.items()},
        shares=kept[0],
        member_shares=kept[1:] if size > 1 else None,
        apart=apart_limits(scenes, length),
        spreads={c: v.spread if math.isfinite(v.spread) else None for c, v in pinned.items()},
        spread_anchors={c: v.anchor for c, v in pinned.items()},
    )
