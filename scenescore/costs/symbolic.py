"""Costs in CasADi: a table from cost type to its symbolic form, and the context a form writes into.

The ``casadi`` solver builds one nonlinear program per problem. For every term of the cost it looks up
the term's form by type (the most specific registered class in the term's MRO, cvxpy style) and calls
``form(term, weight, nlp)``. A form adds objective terms, constraint rows and extra variables to the
:class:`SymbolicProblem`. Every cost has a form: the table's entry for :class:`Cost` evaluates the
term in torch through a ``casadi.Callback`` (value and gradient by autograd), and the entry for
:class:`ConstraintCost` does the same for its rows (Jacobian from :meth:`ConstraintCost.jacobian`).
Built-in costs register exact symbolic forms next to their class; a user extends the table with
:func:`register_casadi_form`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import casadi as ca
import numpy as np
import torch
from torch import Tensor

from ..geometry.footprints import footprint_core
from ..scene.scene import Scene
from .base import ConstraintCost, Cost
from .terms import CostError

__all__ = [
    "SymbolicProblem",
    "CasadiForm",
    "register_casadi_form",
    "casadi_form",
    "objective_by_torch",
    "rows_by_torch",
    "TorchCallback",
]

CasadiForm = Callable[[Any, float, "SymbolicProblem"], None]
_FORMS: dict[type, CasadiForm] = {}


def register_casadi_form(cost_type: type, form: CasadiForm) -> None:
    """Use ``form(term, weight, nlp)`` for terms of ``cost_type`` (and its subclasses without their own)."""
    if not (isinstance(cost_type, type) and issubclass(cost_type, Cost)):
        raise CostError(f"register_casadi_form: expected a Cost subclass, got {cost_type!r}")
    _FORMS[cost_type] = form


def casadi_form(term: Cost) -> CasadiForm:
    """The form registered for the most specific class of ``term``."""
    for cls in type(term).__mro__:
        if cls in _FORMS:
            return _FORMS[cls]
    raise CostError(f"no CasADi form for {type(term).__name__}")  # unreachable: Cost has one


class SymbolicProblem:
    """The NLP under construction: poses as CasADi expressions, objective, rows, extra variables.

    ``poses`` is ``(N, 3)``: movable objects' rows are the decision variables ``z``, the others the
    parameters ``p`` (their poses at solve time). ``options`` carries the solver's options (e.g.
    ``energy``: ``"mx"`` or ``"callback"``).
    """

    def __init__(self, scene: Scene, movable: np.ndarray, base: Tensor, options: dict[str, Any]):
        self.scene = scene
        self.options = options
        self.base = base  # (N, 3) float64: the poses of objects that do not move
        n = len(scene)
        self.var_obj = [int(i) for i in np.flatnonzero(movable)]
        self.nz = 3 * len(self.var_obj)
        self.z = ca.MX.sym("z", self.nz)
        self.p = ca.MX.sym("p", n, 3)
        slot = {ob: k for k, ob in enumerate(self.var_obj)}
        self.poses = ca.vertcat(
            *[self.z[3 * slot[i] : 3 * slot[i] + 3].T if i in slot else self.p[i, :] for i in range(n)]
        )
        self.objective: Any = 0
        self.g: list[Any] = []
        self.lbg: list[float] = []
        self.ubg: list[float] = []
        self.extra: list[tuple[Any, Callable[[np.ndarray], np.ndarray]]] = []  # (symbols, start(x0))
        self.callbacks: list[ca.Callback] = []  # kept alive as long as the NLP
        self.exact_hessian = True
        self._cores = [footprint_core(o) for o in scene.objects]

    # -- what forms call -------------------------------------------------------------------------------
    def add_objective(self, expr: Any) -> None:
        self.objective = self.objective + expr

    def add_rows(
        self, rows: Any, lb: float | Sequence[float] | np.ndarray, ub: float | Sequence[float] | np.ndarray
    ) -> None:
        """Constraint rows ``lb <= rows <= ub`` (``rows``: an expression, column, or list of scalars)."""
        col = ca.vertcat(*rows) if isinstance(rows, list) else rows
        m = int(col.shape[0])
        self.g.append(col)
        self.lbg += list(np.broadcast_to(np.asarray(lb, dtype=float), (m,)))
        self.ubg += list(np.broadcast_to(np.asarray(ub, dtype=float), (m,)))

    def add_variables(self, symbols: Any, start: Callable[[np.ndarray], np.ndarray]) -> None:
        """Extra decision variables; ``start(x0 (N, 3))`` gives their initial values for a solve."""
        self.extra.append((symbols, start))

    def footprint_vertices(self, i: int) -> tuple[list[tuple[Any, Any]], float]:
        """Object ``i``'s placed core vertices as expressions, and the radius grown around them."""
        core, r = self._cores[i]
        c, s = ca.cos(self.poses[i, 2]), ca.sin(self.poses[i, 2])
        x, y = self.poses[i, 0], self.poses[i, 1]
        return [(x + c * px - s * py, y + s * px + c * py) for px, py in core], r

    def torch_function(self, fn: Callable[[Tensor], Tensor], rows: int = 0) -> Any:
        """``fn(poses (1, N, 3)) -> (1,)`` (``rows == 0``) or ``(1, rows)`` as a CasADi expression of ``z``.

        Values and derivatives come from torch (on the device of the problem's poses); IPOPT then uses its
        limited-memory Hessian.
        """
        base, var = self.base, self.var_obj

        def of_z(zt: Tensor) -> Tensor:
            x = base.clone()
            x[var] = zt.reshape(-1, 3).to(x.device)
            return fn(x[None]).reshape(-1)

        cb = TorchCallback(f"torch_{len(self.callbacks)}", of_z, self.nz, max(rows, 1))
        self.callbacks.append(cb)
        self.exact_hessian = False
        return cb(self.z)


class TorchCallback(ca.Callback):
    """A torch function of ``n`` variables with ``m`` outputs (Jacobian by autograd) as a CasADi function."""

    def __init__(self, name: str, fn: Callable[[Tensor], Tensor], n: int, m: int = 1):
        ca.Callback.__init__(self)
        self.fn, self.n, self.m = fn, n, m
        self._jac: ca.Callback | None = None
        self.construct(name, {"enable_fd": False})

    def get_n_in(self) -> int:
        return 1

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> Any:
        return ca.Sparsity.dense(self.n, 1)

    def get_sparsity_out(self, i: int) -> Any:
        return ca.Sparsity.dense(self.m, 1)

    def eval(self, arg: Any) -> list[Any]:
        z = torch.as_tensor(np.asarray(arg[0]).ravel(), dtype=torch.float64)
        with torch.no_grad():
            return [self.fn(z).detach().cpu().numpy().reshape(self.m, 1)]

    def has_jacobian(self) -> bool:
        return True

    def get_jacobian(self, name: str, inames: Any, onames: Any, opts: Any) -> ca.Callback:
        self._jac = _TorchJacobian(name, self.fn, self.n, self.m, opts)
        return self._jac


class _TorchJacobian(ca.Callback):
    def __init__(self, name: str, fn: Callable[[Tensor], Tensor], n: int, m: int, opts: Any):
        ca.Callback.__init__(self)
        self.fn, self.n, self.m = fn, n, m
        self.construct(name, opts)

    def get_n_in(self) -> int:
        return 2

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> Any:
        return ca.Sparsity.dense(self.n, 1) if i == 0 else ca.Sparsity.dense(self.m, 1)

    def get_sparsity_out(self, i: int) -> Any:
        return ca.Sparsity.dense(self.m, self.n)

    def eval(self, arg: Any) -> list[Any]:
        z = torch.as_tensor(np.asarray(arg[0]).ravel(), dtype=torch.float64)
        jac = torch.autograd.functional.jacobian(lambda v: self.fn(v).reshape(-1), z)
        return [jac.detach().cpu().numpy().reshape(self.m, self.n)]


def objective_by_torch(term: Cost, weight: float, nlp: SymbolicProblem) -> None:
    """Any cost: its torch value and gradient through a callback."""
    nlp.add_objective(weight * nlp.torch_function(lambda x: term(x)))


def rows_by_torch(term: ConstraintCost, weight: float, nlp: SymbolicProblem) -> None:
    """Any constraint cost: its rows ``g >= 0`` through a callback (hard constraints; the weight is moot)."""
    m = len(term.labels())
    if m:
        nlp.add_rows(nlp.torch_function(lambda x: term.constraints(x), rows=m), 0.0, ca.inf)


register_casadi_form(Cost, objective_by_torch)
register_casadi_form(ConstraintCost, rows_by_torch)
