"""Scenes as padded tensors: the batches the energy network, training and the samplers work on."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import Tensor

from ..encoders import Encoder, encode_scene
from ..scene.scene import Bounds, Scene, SceneError, SceneObject

__all__ = ["SceneTensors", "batch_scenes", "wall_objects"]


@dataclass
class SceneTensors:
    """Scenes as padded tensors; ``mask`` marks real objects, ``known`` known poses, ``fixed`` fixed ones,
    ``round`` round disks (their headings mean nothing)."""

    poses: Tensor  # (B, N, 3), unknown poses are 0
    feats: Tensor  # (B, N, F)
    sizes: Tensor  # (B, N, 2)
    mask: Tensor  # (B, N) bool
    known: Tensor  # (B, N) bool
    fixed: Tensor  # (B, N) bool
    round: Tensor  # (B, N) bool
    lo: Tensor  # (B, 2) lower bounds
    hi: Tensor  # (B, 2) upper bounds

    def __len__(self) -> int:
        return self.poses.shape[0]

    def index(self, idx: Tensor | Sequence[int]) -> SceneTensors:
        """Rows ``idx`` (an index tensor or list)."""
        idx = torch.as_tensor(idx, dtype=torch.long, device=self.poses.device)
        return SceneTensors(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def repeat(self, k: int) -> SceneTensors:
        """Each scene ``k`` times in a row: ``(B * k, ...)``."""
        return SceneTensors(
            *(getattr(self, f).repeat_interleave(k, dim=0) for f in self.__dataclass_fields__)
        )

    def to(self, device: torch.device | str) -> SceneTensors:
        """The same tensors on ``device`` (itself when they are there already)."""
        if self.poses.device == torch.device(device):
            return self
        return SceneTensors(*(getattr(self, f).to(device) for f in self.__dataclass_fields__))


WALL_COLOR = (200, 200, 200)
WALL_THICKNESS = 0.02  # of the bounds' larger side


def wall_objects(bounds: Bounds) -> list[SceneObject]:
    """The four sides of the bounds as thin fixed boxes just outside them, each heading so that its own
    ``+y`` points into the room (south, north, west, east). They scale with the bounds."""
    (x0, y0), (x1, y1) = bounds
    w, h = x1 - x0, y1 - y0
    t = WALL_THICKNESS * max(w, h)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    sides = [
        ("s", (cx, y0 - t / 2, 0.0), w + 2 * t),
        ("n", (cx, y1 + t / 2, math.pi), w + 2 * t),
        ("w", (x0 - t / 2, cy, -math.pi / 2), h + 2 * t),
        ("e", (x1 + t / 2, cy, math.pi / 2), h + 2 * t),
    ]
    return [
        SceneObject(f"wall_{k}", "wall", (length, t), pose, color=WALL_COLOR, fixed=True)
        for k, pose, length in sides
    ]


def batch_scenes(
    scenes: Sequence[Scene],
    encoder: Encoder,
    dtype: torch.dtype = torch.float32,
    walls: bool = False,
    device: torch.device | str | None = None,
) -> SceneTensors:
    """Encode and pad scenes of possibly different sizes into one batch; ``walls`` appends the bounds'
    four sides to every scene as fixed objects (after its own objects, which keep their indices).
    The batch is filled on the CPU and moved to ``device`` (default the CPU) in one copy per tensor."""
    if not scenes:
        raise SceneError("batch_scenes: no scenes given")
    if walls:
        scenes = [Scene([*s.objects, *wall_objects(s.bounds)], s.bounds) for s in scenes]
    b, n = len(scenes), max(len(s) for s in scenes)
    out = SceneTensors(
        poses=torch.zeros(b, n, 3, dtype=dtype),
        feats=torch.zeros(b, n, encoder.dim, dtype=dtype),
        sizes=torch.zeros(b, n, 2, dtype=dtype),
        mask=torch.zeros(b, n, dtype=torch.bool),
        known=torch.zeros(b, n, dtype=torch.bool),
        fixed=torch.zeros(b, n, dtype=torch.bool),
        round=torch.zeros(b, n, dtype=torch.bool),
        lo=torch.zeros(b, 2, dtype=dtype),
        hi=torch.zeros(b, 2, dtype=dtype),
    )
    for k, s in enumerate(scenes):
        m = len(s)
        out.poses[k, :m] = torch.as_tensor(s.poses(), dtype=dtype)
        out.feats[k, :m] = torch.as_tensor(encode_scene(s, encoder), dtype=dtype)
        out.sizes[k, :m] = torch.as_tensor(s.sizes(), dtype=dtype)
        out.mask[k, :m] = True
        out.known[k, :m] = torch.tensor([o.pose is not None for o in s.objects])
        out.fixed[k, :m] = torch.tensor([o.fixed for o in s.objects])
        out.round[k, :m] = torch.tensor([o.round for o in s.objects])
        out.lo[k] = torch.tensor(s.bounds[0], dtype=dtype)
        out.hi[k] = torch.tensor(s.bounds[1], dtype=dtype)
    return out if device is None else out.to(device)
