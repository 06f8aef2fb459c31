"""What a cost term is bound to and what it gives back: the :class:`Binding` to a problem's scene, a
term's value in a sum (:class:`TermValue`), a violated constraint (:class:`Violation`), the checks every
term's values and object names pass, and :class:`CostError`, the error of a cost used wrongly."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from ..geometry.footprints import Footprints
from ..runtime import resolve_device
from ..scene.scene import Scene, SceneError
from . import finite

__all__ = ["CostError", "Binding", "TermValue", "Violation", "check_values", "check_scene_names"]


class CostError(ValueError):
    """A cost used wrongly: unbound, a bad pose tensor, a duplicate name, a non-finite value."""


@dataclass
class Binding:
    """What a bound cost knows of its problem: the scene, which objects move, the footprints, and the
    device its tensors live on (the poses it is evaluated at must be there too)."""

    scene: Scene
    movable: np.ndarray  # (N,) bool
    footprints: Footprints
    device: torch.device = field(default_factory=lambda: torch.device("cpu"))

    @classmethod
    def make(
        cls,
        scene: Scene,
        movable: np.ndarray | list[str] | None = None,
        device: str | torch.device | None = None,
    ) -> Binding:
        n = len(scene)
        if movable is None:
            mask = np.array([not o.fixed for o in scene.objects])
        elif isinstance(movable, np.ndarray) and movable.dtype == bool:
            mask = movable.copy()
        else:
            mask = np.zeros(n, dtype=bool)
            for name in movable:
                mask[scene.index(name)] = True
        if mask.shape != (n,):
            raise CostError(f"movable: expected {n} flags, got shape {mask.shape}")
        dev = resolve_device(device)
        return cls(scene, mask, Footprints.from_scene(scene, device=dev), dev)


@dataclass
class TermValue:
    """One term of a sum at a batch of poses: its raw value, weight, weighted value and violation."""

    value: Tensor  # (B,)
    weight: float
    weighted: Tensor  # (B,)
    violation: Tensor | None  # (B,), metres (or radians); None for terms that are not constraints


@dataclass
class Violation:
    """One violated constraint found by an exact check: the term, the row's label, by how much (metres)."""

    term: str
    label: str
    amount: float
    text: str = ""  # a sentence for people; default "<label> violated by <amount> mm"

    def describe(self) -> str:
        return self.text or f"{self.term}: {self.label} violated by {self.amount * 1000:.2f} mm"


def check_values(values: Tensor, name: str, rows: int) -> None:
    """A term's values ``(rows,)``: the shape at once; finiteness at once or, inside
    :func:`~scenescore.costs.finite.watching` (a chain's steps), recorded for the chain's end."""
    if values.shape != (rows,):
        raise CostError(f"cost term {name!r}: expected values of shape ({rows},), got {tuple(values.shape)}")
    watch = finite.current()
    if watch is not None:
        watch.record(name, values)
    elif not torch.isfinite(values).all():
        bad = int((~torch.isfinite(values)).nonzero()[0, 0])
        raise CostError(f"cost term {name!r} is not finite (NaN or inf) at batch row {bad}")


def check_scene_names(scene: Scene, names: Sequence[str], what: str) -> list[int]:
    """Indices of ``names``; the error names the cost option and the objects there are."""
    out = []
    for n in names:
        try:
            out.append(scene.index(n))
        except SceneError:
            raise CostError(f"{what}: no object named {n!r}; objects are {scene.names}") from None
    return out
