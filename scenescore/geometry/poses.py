"""Poses as batched tensors ``(..., 3)`` of ``(x, y, theta)``: composed, related, drawn inside bounds."""

from __future__ import annotations

import math

import torch
from torch import Tensor

from ..runtime import draw

__all__ = ["compose_poses", "relative_poses", "uniform_init"]


def compose_poses(a: Tensor, b: Tensor) -> Tensor:
    """Poses ``a * b`` (``b`` in ``a``'s frame), ``(..., 3)``."""
    c, s = torch.cos(a[..., 2]), torch.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return torch.stack([x, y, a[..., 2] + b[..., 2]], dim=-1)


def relative_poses(a: Tensor, b: Tensor) -> Tensor:
    """Pose of ``b`` in ``a``'s frame, ``(..., 3)``."""
    c, s = torch.cos(a[..., 2]), torch.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return torch.stack([c * dx + s * dy, -s * dx + c * dy, b[..., 2] - a[..., 2]], dim=-1)


def uniform_init(
    shape: tuple[int, int],
    lo: Tensor,
    hi: Tensor,
    generator: torch.Generator,
    dtype: torch.dtype = torch.float32,
) -> Tensor:
    """Poses uniform inside the bounds, angles uniform: ``(B, N, 3)`` on the device of ``lo``; ``lo``/``hi``
    are ``(2,)`` or ``(B, 2)``."""
    b, n = shape
    u = draw("rand", (b, n, 3), generator, lo.device, dtype)
    lo = lo.to(dtype).reshape(-1, 1, 2)
    hi = hi.to(dtype).reshape(-1, 1, 2)
    xy = lo + u[..., :2] * (hi - lo)
    th = (u[..., 2:] * 2 - 1) * math.pi
    return torch.cat([xy, th], dim=-1)
