"""The flags a placed object gets (:func:`assess`), each from its own check against the model's
:class:`~scenescore.models.trust.TrustReference`: ``energy`` and ``members`` (its share of the energy),
``far``, ``apart``, ``bound``, ``novel``, and the model's own caveats (:mod:`scenescore.models.trust`
says what each means); and a note, no flag, when the examples leave the object's category free
(``free``: :mod:`scenescore.models.freedom`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import torch

from ..scene.scene import Scene
from ..scene.units import length_unit
from .layout import BOUND_TOL, nearest_distances, touching_bound
from .shares import energy_per_object, shares_by_energy
from .trust import (
    CAVEAT,
    FAR_FACTOR,
    Assessment,
    TrustReference,
    apart_distances,
    members_doubt,
    members_needed,
)

__all__ = ["assess"]


@dataclass
class _Seen:
    """What :func:`assess` reads of a scene once, for every object it judges: each object's share of
    the energy (``share``; each member's, ``per_member``, for an ensemble the reference judges), or the
    scene's energy per object (``energy``, a reference from before the shares); the poses, each object's
    nearest distance in length scales, its encoded features, the model's caveats and the scene's unit."""

    share: dict[str, float] | None
    per_member: np.ndarray | None
    energy: float | None
    poses: np.ndarray
    nearest: np.ndarray
    feats: torch.Tensor
    caveats: Any
    unit: str


def _seen(
    ref: TrustReference, model: Any, scene: Scene, names: Sequence[str], feats: torch.Tensor | None
) -> _Seen:
    share = per_member = energy = None
    if ref.shares:
        judged = bool(ref.member_shares) and getattr(model, "members", 1) == len(ref.member_shares or [])
        rows = shares_by_energy(model, scene, names, members=judged)
        share = dict(zip(names, rows[0].tolist()))
        per_member = rows[1:] if judged else None
    else:  # a checkpoint from before the shares were stored: the scene's energy per object
        energy = float(energy_per_object(model, [scene])[0])
    if feats is None:
        with torch.no_grad():
            feats = model.tensors([scene]).feats[0]
    poses = scene.poses()
    return _Seen(
        share,
        per_member,
        energy,
        poses,
        nearest_distances(poses) / ref.length_scale,
        feats,
        getattr(getattr(model, "info", None), "caveats", None),  # the model's ``info.caveats``
        length_unit(scene),
    )


def _energy_verdict(
    ref: TrustReference, seen: _Seen, k: int, name: str, category: str
) -> tuple[float, list[str]]:
    """The confidence in object ``name`` (the ``k``-th judged) by its energy, and the ``energy`` and
    ``members`` flags: its share beyond every one of its category's in the data, or (an ensemble) beyond
    for most members (:func:`~scenescore.models.trust.members_needed`); for a reference without shares,
    the scene's energy beyond every example's."""
    if seen.share is None:
        ref_e = np.asarray(ref.energies)
        e = cast(float, seen.energy)
        if not ref_e.size:
            return 1.0, []
        flags = []
        if e > ref.energy_limit:
            flags.append(
                f"energy: the scene's energy {e:.3g} per object lies beyond every example's "
                f"({ref.energy_limit:.3g})"
            )
        return float(np.mean(ref_e >= e)), flags
    assert ref.shares is not None  # the share was measured: the reference has them
    mine, limit = ref.category_shares(category), ref.share_limit(category)
    whose = f"any {category}'s" if category in ref.shares else "any object's"
    confidence = float(np.mean(mine >= seen.share[name]))
    flags = []
    if seen.share[name] > limit:
        flags.append(
            f"energy: its share of the scene's energy {seen.share[name]:.3g} lies beyond {whose} in the "
            f"data ({limit:.3g})"
        )
    if seen.per_member is not None:
        members_confidence, doubt = members_doubt(ref, category, seen.per_member[:, k])
        confidence = min(members_confidence, confidence)
        size = len(seen.per_member)
        if doubt >= members_needed(size):
            split = " (the ensemble disagrees)" if doubt < size else ""
            flags.append(
                f"members: {doubt} of {size} members put its share of their energy "
                f"beyond {whose} in the data{split}"
            )
    return confidence, flags


def _far_flags(ref: TrustReference, seen: _Seen, i: int, category: str) -> list[str]:
    """``far``: farther from its nearest neighbour than :data:`FAR_FACTOR` times any of its category in
    the data."""
    far = ref.nearest.get(category, ref.nearest_any)
    if not (math.isfinite(seen.nearest[i]) and far > 0 and seen.nearest[i] > FAR_FACTOR * far):
        return []
    d, lim = seen.nearest[i] * ref.length_scale, far * ref.length_scale
    return [
        f"far: {d:.3g} {seen.unit} from its nearest neighbour; no {category} in the data is more than "
        f"{lim:.3g} {seen.unit} away"
    ]


def _apart_flags(ref: TrustReference, scene: Scene, seen: _Seen, i: int, category: str) -> list[str]:
    """``apart``: farther from every object of some category than :data:`FAR_FACTOR` times any of its
    category in the data."""
    return [
        f"apart: {d[0]:.3g} {seen.unit} from the nearest {c}; no {category} in the data is more "
        f"than {limit:.3g} {seen.unit} from one"
        for c, d, limit in apart_distances(ref, scene, i, seen.poses[None])
        if d[0] > FAR_FACTOR * limit
    ]


def _bound_flags(ref: TrustReference, scene: Scene, seen: _Seen, i: int) -> list[str]:
    """``bound``: pinned at a bound that no object of its category in the data touches."""
    o = scene.objects[i]
    side = touching_bound(o, seen.poses[i], scene.bounds, BOUND_TOL * ref.length_scale)
    if not side or ref.may_touch_bounds(o.category):
        return []
    return [f"bound: pinned at the bound {side}, {ref.bound_reason(o.category, seen.unit)}"]


def _novel_flags(ref: TrustReference, seen: _Seen, i: int) -> list[str]:
    """``novel``: features farther from every object seen in training than the reference's radius."""
    known = np.asarray(ref.features)
    if not known.size:
        return []
    dist = float(np.linalg.norm(known - seen.feats[i].double().cpu().numpy(), axis=1).min())
    if dist <= ref.feature_radius:
        return []
    return [
        f"novel: its features are {dist:.2f} from any object seen in training (limit {ref.feature_radius:.2f})"
    ]


def assess(
    ref: TrustReference, model: Any, scene: Scene, names: Sequence[str], feats: torch.Tensor | None = None
) -> dict[str, Assessment]:
    """Confidence and flags for the objects ``names`` of ``scene`` (every pose known), each flag from
    its own check: ``energy`` and ``members`` (:func:`_energy_verdict`), ``far``, ``apart``, ``bound``,
    ``novel``, and the model's own caveats about the category.

    ``feats``: the scene's encoded features ``(N, F)`` when the caller has them (saves encoding again).
    """
    seen = _seen(ref, model, scene, names, feats)
    out = {}
    for k, name in enumerate(names):
        i = scene.index(name)
        cat = scene.objects[i].category
        confidence, flags = _energy_verdict(ref, seen, k, name, cat)
        flags += _far_flags(ref, seen, i, cat)
        flags += _apart_flags(ref, scene, seen, i, cat)
        flags += _bound_flags(ref, scene, seen, i)
        flags += _novel_flags(ref, seen, i)
        if seen.caveats is not None:
            flags += [CAVEAT + reason for reason in seen.caveats.reasons(cat)]
        out[name] = Assessment(confidence, flags, _free_notes(ref, cat, seen.unit))
    return out


def _free_notes(ref: TrustReference, cat: str, unit: str) -> list[str]:
    """``free``: the examples leave the category's place free (:mod:`~scenescore.models.freedom`), so
    the placement is one the data allows, not the one it shows."""
    spread = ref.spread(cat)
    if spread is None or not spread.free:
        return []
    if not math.isfinite(spread.spread):
        return [f"free: one example scene alone shows a {cat}, so the examples do not pin its place down"]
    return [
        f"free: the examples leave a {cat}'s place free (they disagree by {spread.spread * ref.length_scale:.3g} "
        f"{unit} at best, beside {spread.anchor})"
    ]
