"""Cost objects: named, batched, differentiable terms that sum into one flat weighted objective.

A cost maps poses ``(B, N, 3)`` to ``(B,)``. ``w * cost`` and ``cost + cost`` build a :class:`Sum`, a flat
list of ``(weight, term)`` (sums never nest); two terms with one name are an error. Costs that need the
scene (footprints, names, which objects move) are *bound* to it with :meth:`Cost.bind`, which returns a
bound copy; :class:`~scenescore.problem.problem.Problem` does this for you.

Constraint-like costs (collision, bounds, reach) also expose their constraints as ``g(poses) >= 0``
rows in metres; their penalty is ``sum(relu(-g) ** power)`` and their violation is ``max(relu(-g))``.

A cost is one class: its torch evaluation (``evaluate``), its constraint rows (``constraints``), its
exact feasibility check (``check``: :class:`~scenescore.problem.problem.Problem` asks every term), and, in the
cost's own module, its CasADi form (:func:`scenescore.costs.symbolic.register_casadi_form`) and its YAML
spec (:func:`scenescore.costs.spec.register_cost_type`). See ``docs/extending.md``. A term with an
opinion on candidate poses beyond its value (it proposes some, doubts others: the learned energy) is also
a :class:`~scenescore.costs.guide.Guide`.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Iterator, Sequence
from typing import cast

import numpy as np
import torch
from torch import Tensor

from ..scene.scene import Scene
from .terms import Binding, CostError, TermValue, Violation, check_values

__all__ = ["Cost", "ConstraintCost", "Sum", "as_sum", "stack_sums"]


class Cost:
    """Base of all costs: ``name``, ``evaluate(poses (B, N, 3)) -> (B,)``, algebra, binding."""

    name: str = "cost"
    needs_scene: bool = False
    _binding: Binding | None = None

    # -- the contract -------------------------------------------------------------------------------
    def evaluate(self, poses: Tensor) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def violation(self, poses: Tensor) -> Tensor | None:
        """Largest violation per batch row ``(B,)``, or ``None`` when the cost is not a constraint."""
        return None

    @property
    def is_constraint(self) -> bool:
        return False

    def _on_bind(self) -> None:
        """Precompute whatever depends on the scene (subclasses)."""

    def check(self, poses: np.ndarray, tol: float) -> list[Violation]:
        """The exact check of one pose set ``(N, 3)``: what this term violates by more than ``tol``."""
        return []

    # -- binding ------------------------------------------------------------------------------------
    def model_device(self) -> torch.device | None:
        """The device of the model this term evaluates (a learned energy's), or None: it has none and
        works wherever it is bound."""
        return None

    def bind(
        self,
        scene: Scene,
        movable: np.ndarray | list[str] | None = None,
        device: str | torch.device | None = None,
    ) -> Cost:
        """A copy of this cost bound to ``scene`` (``movable``: names or an ``(N,)`` mask; default: not fixed),
        its tensors on ``device`` (default: :meth:`model_device`, else the CPU); :meth:`_on_bind` makes
        them on ``self.binding.device``."""
        out = copy.copy(self)
        out._binding = Binding.make(scene, movable, device or self.model_device())
        out._on_bind()
        return out

    @property
    def binding(self) -> Binding:
        if self._binding is None:
            raise CostError(
                f"cost {self.name!r} ({type(self).__name__}) is not bound to a scene: "
                "use ss.Problem(scene, cost) or cost.bind(scene)"
            )
        return self._binding

    def _check(self, poses: Tensor) -> Tensor:
        if not isinstance(poses, Tensor):
            raise CostError(
                f"cost {self.name!r}: expected poses as a torch tensor (B, N, 3), got {type(poses).__name__}"
            )
        if poses.dim() != 3 or poses.shape[-1] != 3:
            raise CostError(
                f"cost {self.name!r}: expected poses of shape (B, N, 3), got {tuple(poses.shape)}"
            )
        if self._binding is not None and poses.shape[1] != len(self._binding.scene):
            raise CostError(
                f"cost {self.name!r}: poses have {poses.shape[1]} objects, the scene has {len(self._binding.scene)}"
            )
        if not poses.is_floating_point():
            raise CostError(f"cost {self.name!r}: expected floating-point poses, got {poses.dtype}")
        return poses

    @classmethod
    def stack(cls, terms: Sequence[Cost], sizes: Sequence[int]) -> Callable[[Tensor], Tensor]:
        """One batched function for several bound copies of this term (one per problem): rows of its
        input ``(sum(sizes), N, 3)`` come in contiguous groups of ``sizes``, group ``k`` for ``terms[k]``.
        The default evaluates each group with its own term; a term that can fuse the groups overrides it."""
        ends = np.cumsum(sizes).tolist()
        starts = [0, *ends[:-1]]

        def fn(poses: Tensor) -> Tensor:
            return torch.cat([t(poses[a:b]) for t, a, b in zip(terms, starts, ends)])

        return fn

    def __call__(self, poses: Tensor) -> Tensor:
        if self.needs_scene:
            self.binding  # noqa: B018 - raises a clear error when unbound
        return self.evaluate(self._check(poses))

    # -- algebra ------------------------------------------------------------------------------------
    def __mul__(self, w: float) -> Sum:
        return Sum([(_weight(w, self.name), self)])

    __rmul__ = __mul__

    def __add__(self, other: Cost) -> Sum:
        return as_sum(self) + other

    def __radd__(self, other: object) -> Sum:
        if other == 0:  # sum([...]) starts from 0
            return as_sum(self)
        return NotImplemented

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"


class ConstraintCost(Cost):
    """A cost defined by constraint rows ``g(poses) >= 0`` (metres): penalty ``sum(relu(-g) ** power)``."""

    needs_scene = True
    power: float = 1.0

    @property
    def is_constraint(self) -> bool:
        return True

    def constraints(self, poses: Tensor) -> Tensor:  # pragma: no cover - abstract
        """Rows ``(B, M)``; feasible where every row is ``>= 0``."""
        raise NotImplementedError

    def constraints_below(self, poses: Tensor, floor: Tensor) -> Tensor:
        """Rows ``(B, M)`` for a caller that needs them only where they may be below ``floor (B, M)``:
        exact there; elsewhere any value above ``floor`` (a term with a cheap lower bound skips those
        rows). The default computes every row."""
        return self.constraints(poses)

    def labels(self) -> list[str]:  # pragma: no cover - abstract
        """A short label per row (``"mug / plate_0"``, ``"mug: x >= -0.6"``)."""
        raise NotImplementedError

    def support(self) -> list[tuple[int, ...]]:  # pragma: no cover - abstract
        """The objects each row depends on."""
        raise NotImplementedError

    def jacobian(self, poses: Tensor) -> tuple[Tensor, Tensor]:
        """Rows and their Jacobian: ``g (B, M)``, ``dg/dposes (B, M, N, 3)`` (one batched backward pass)."""
        poses = self._check(poses).detach()
        b, n, _ = poses.shape
        m = len(self.labels())
        if m == 0:
            return poses.new_zeros(b, 0), poses.new_zeros(b, 0, n, 3)
        with torch.enable_grad():
            x = poses[:, None].expand(b, m, n, 3).reshape(b * m, n, 3).clone().requires_grad_(True)
            g = self.constraints(x).reshape(b, m, m)
            diag = torch.diagonal(g, dim1=1, dim2=2)  # (B, M): row k evaluated on copy k
            (jac,) = torch.autograd.grad(diag.sum(), x)
        return diag.detach(), jac.reshape(b, m, n, 3)

    def project(self, poses: Tensor, movable: Tensor) -> Tensor:
        """Closed-form projection onto the constraint set where one exists (default: none)."""
        return poses

    def evaluate(self, poses: Tensor) -> Tensor:
        g = self.constraints(poses)
        if g.shape[-1] == 0:
            return poses.new_zeros(poses.shape[0])
        return (torch.relu(-g) ** self.power).sum(-1)

    def violation(self, poses: Tensor) -> Tensor:
        poses = self._check(poses)
        g = self.constraints(poses)
        if g.shape[-1] == 0:
            return poses.new_zeros(poses.shape[0])
        return torch.relu(-g).max(-1).values

    def check(self, poses: np.ndarray, tol: float) -> list[Violation]:
        """Default exact check: every row below ``-tol`` at ``poses (N, 3)``, evaluated in float64."""
        x = torch.as_tensor(np.asarray(poses, dtype=np.float64), device=self.binding.device).reshape(1, -1, 3)
        with torch.no_grad():
            g = self.constraints(self._check(x))[0].cpu()
        labels = self.labels()
        return [Violation(self.name, labels[k], float(-g[k])) for k in range(len(g)) if float(g[k]) < -tol]

    def worst(self, poses: Tensor) -> tuple[str, float] | None:
        """The most violated row at one pose set ``(N, 3)`` or ``(1, N, 3)``: ``(label, violation)``."""
        p = poses.reshape(1, -1, 3)
        g = self.constraints(self._check(p))[0]
        if g.numel() == 0:
            return None
        k = int(torch.argmin(g))
        return self.labels()[k], float(torch.relu(-g[k]))


def _weight(w: object, name: str) -> float:
    if isinstance(w, bool) or not isinstance(w, (int, float)):
        raise CostError(f"weight of {name!r}: expected a number, got {w!r}")
    if not math.isfinite(w) or w < 0:
        raise CostError(f"weight of {name!r}: expected a finite number >= 0, got {w!r}")
    return float(w)


class Sum(Cost):
    """A flat weighted sum of named terms; ``terms(poses)`` gives each term's breakdown."""

    name = "total"
    items: list[tuple[float, Cost]]

    def __init__(self, terms: list[tuple[float, Cost]]):
        flat: list[tuple[float, Cost]] = []
        for w, c in terms:
            if isinstance(c, Sum):
                flat.extend((w * w2, c2) for w2, c2 in c.items)
            elif isinstance(c, Cost):
                flat.append((w, c))
            else:
                raise CostError(f"cannot add {type(c).__name__} to a cost: expected a scenescore Cost")
        seen: set[str] = set()
        for _, c in flat:
            if c.name in seen:
                raise CostError(
                    f"two cost terms are named {c.name!r}; names must be unique: pass name=... to one of them"
                )
            seen.add(c.name)
        self.items = flat

    @property
    def needs_scene(self) -> bool:  # type: ignore[override]
        return any(c.needs_scene for _, c in self.items)

    def __iter__(self) -> Iterator[tuple[float, Cost]]:
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, name: str) -> Cost:
        for _, c in self.items:
            if c.name == name:
                return c
        raise CostError(f"no cost term named {name!r}; terms are {self.names}")

    @property
    def names(self) -> list[str]:
        return [c.name for _, c in self.items]

    def weight(self, name: str) -> float:
        for w, c in self.items:
            if c.name == name:
                return w
        raise CostError(f"no cost term named {name!r}; terms are {self.names}")

    def model_device(self) -> torch.device | None:
        """The first term's model device (see :meth:`Cost.model_device`)."""
        return next((d for d in (c.model_device() for _, c in self.items) if d is not None), None)

    def bind(
        self,
        scene: Scene,
        movable: np.ndarray | list[str] | None = None,
        device: str | torch.device | None = None,
    ) -> Sum:
        binding = Binding.make(scene, movable, device or self.model_device())
        out = Sum([(w, c.bind(scene, binding.movable, binding.device)) for w, c in self.items])
        out._binding = binding
        return out

    def __mul__(self, w: float) -> Sum:
        w = _weight(w, self.name)
        return Sum([(w * w2, c) for w2, c in self.items])

    __rmul__ = __mul__

    def __add__(self, other: Cost) -> Sum:
        if not isinstance(other, Cost):
            return NotImplemented
        return Sum([*self.items, *as_sum(other).items])

    def evaluate(self, poses: Tensor) -> Tensor:
        total = poses.new_zeros(poses.shape[0])
        for w, c in self.items:
            v = c(poses)
            check_values(v, c.name, poses.shape[0])
            total = total + w * v
        return total

    def terms(self, poses: Tensor) -> dict[str, TermValue]:
        """Every term's value, weight, weighted value and violation at ``poses (B, N, 3)``."""
        poses = self._check(poses)
        out = {}
        for w, c in self.items:
            v = c(poses)
            check_values(v, c.name, poses.shape[0])
            out[c.name] = TermValue(v, w, w * v, c.violation(poses) if c.is_constraint else None)
        return out

    def violation(self, poses: Tensor) -> Tensor | None:
        vs = cast(list[Tensor], [c.violation(poses) for _, c in self.items if c.is_constraint])
        if not vs:
            return None
        return torch.stack(vs, dim=-1).max(-1).values

    @property
    def constraint_terms(self) -> list[ConstraintCost]:
        return [c for _, c in self.items if isinstance(c, ConstraintCost)]

    @property
    def objective_items(self) -> list[tuple[float, Cost]]:
        """The terms that are not constraints (the objective of a constrained refinement)."""
        return [(w, c) for w, c in self.items if not c.is_constraint]

    def __repr__(self) -> str:
        return " + ".join(f"{w:g} * {c!r}" for w, c in self.items)


def stack_sums(sums: Sequence[Sum], sizes: Sequence[int]) -> Callable[[Tensor], Tensor]:
    """One batched function for several problems' costs (see :meth:`Cost.stack`): term by term when
    every sum has the same terms and weights (so terms can fuse), else each sum on its own group."""
    first = sums[0]
    same = all(
        [(w, c.name, type(c)) for w, c in s.items] == [(w, c.name, type(c)) for w, c in first.items]
        for s in sums
    )
    if not same:
        return Cost.stack(sums, sizes)
    parts = [
        (w, c.name, type(c).stack([s.items[k][1] for s in sums], sizes))
        for k, (w, c) in enumerate(first.items)
    ]

    def fn(poses: Tensor) -> Tensor:
        total = poses.new_zeros(poses.shape[0])
        for w, name, f in parts:
            v = f(poses)
            check_values(v, name, poses.shape[0])
            total = total + w * v
        return total

    return fn


def as_sum(cost: Cost) -> Sum:
    """``cost`` as a :class:`Sum` (a sum is returned as is)."""
    if isinstance(cost, Sum):
        return cost
    if not isinstance(cost, Cost):
        raise CostError(f"expected a scenescore Cost, got {type(cost).__name__}")
    return Sum([(1.0, cost)])
