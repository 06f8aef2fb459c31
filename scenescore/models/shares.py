"""Each object's share of a scene's learned energy: the scene's energy minus the scene's without it.

Unlike the scene's energy, an object's share does not move with how unusual the rest of the scene is,
which makes it the measure the trust check (:mod:`scenescore.models.trust`) compares a placed object by
against the objects of its category in the reference scenes; for an ensemble, by each member's energy too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import torch

from ..scene.scene import Scene

__all__ = ["energy_per_object", "energy_shares", "member_shares", "shares_by_energy"]


def energy_per_object(model: Any, scenes: Sequence[Scene]) -> list[float]:
    """The learned energy of each fully posed scene, divided by its number of objects."""
    with torch.no_grad():
        st = model.tensors(scenes)
        e = model.energy(st.poses, st)
    return [float(v) / len(s) for v, s in zip(e, scenes)]


def energy_shares(model: Any, scene: Scene, names: Sequence[str] | None = None) -> np.ndarray:
    """Each object's share of ``scene``'s learned energy (every pose known): the scene's energy minus
    the energy of the scene without it (a lone object's: the scene's energy), for ``names`` (default all)
    ``(K,)``. Unlike the scene's energy it does not move with how unusual the rest of the scene is."""
    return shares_by_energy(model, scene, names, members=False)[0]


def member_shares(model: Any, scene: Scene, names: Sequence[str] | None = None) -> np.ndarray:
    """:func:`energy_shares` by each member of an ensemble's energy: ``(members, K)`` (one row for a
    single network)."""
    rows = shares_by_energy(model, scene, names, members=True)
    return rows[1:] if len(rows) > 1 else rows


def shares_by_energy(model: Any, scene: Scene, names: Sequence[str] | None, members: bool) -> np.ndarray:
    """The shares by the model's energy, then (``members``, for an ensemble) by each member's, from one
    pass: ``(1 [+ members], K)``. The ensemble's energy is its members' mean, taken here as the network
    takes it, so row 0 is :func:`energy_shares`'s to the bit."""
    names = list(scene.names if names is None else names)
    rest = [
        replace(scene, objects=[o for o in scene.objects if o.name != name])
        for name in names
        if len(scene) > 1
    ]
    with torch.no_grad():
        st = model.tensors([scene, *rest])
        if members and getattr(model, "members", 1) > 1:
            each = model.member_energies(st.poses, st)
            rows = torch.cat([each.mean(dim=0, keepdim=True), each])
        else:
            rows = model.energy(st.poses, st)[None]
    e = rows.double().cpu().numpy()  # (rows, 1 + K)
    return e[:, :1] - e[:, 1:] if rest else e[:, :1].repeat(len(names), axis=1)
