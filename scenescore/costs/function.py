"""Any user-written torch function of the poses as a cost (Python only: YAML never runs code)."""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

from torch import Tensor

from .base import Cost
from .terms import CostError

__all__ = ["CostFn"]


class CostFn(Cost):
    """Any user-written torch function of the poses: ``fn(poses (B, N, 3)) -> (B,)``, differentiable."""

    def __init__(self, fn: Callable[[Tensor], Tensor], name: str | None = None):
        if not callable(fn):
            raise CostError(f"CostFn: expected a callable poses -> (B,), got {type(fn).__name__}")
        self.fn = fn
        self.name = name or cast(str, getattr(fn, "__name__", "fn"))

    def evaluate(self, poses: Tensor) -> Tensor:
        out = self.fn(poses)
        if not isinstance(out, Tensor) or out.shape != (poses.shape[0],):
            got = tuple(out.shape) if isinstance(out, Tensor) else type(out).__name__
            raise CostError(
                f"CostFn {self.name!r}: expected the function to return shape ({poses.shape[0]},), got {got}"
            )
        return out
