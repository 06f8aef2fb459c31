"""Composable costs: named, batched, differentiable terms that sum into one objective.

``ss.costs.LearnedEnergy(model) + 10.0 * ss.costs.HingeCollision(margin=0.01)`` is a flat weighted
:class:`Sum`; ``sum.terms(poses)`` gives every term's value, weight, weighted value and violation.
One module per cost holds its torch form, constraint rows, exact check, CasADi form and YAML spec.
"""

from .base import ConstraintCost, Cost, Sum, as_sum
from .guide import Guide, Verdict
from .spec import CostSpec, SpecContext, cost_types, register_cost_type
from .symbolic import SymbolicProblem, register_casadi_form
from .terms import Binding, CostError, TermValue, Violation

# Each module registers its YAML type on import; errors list the types in this order.
# isort: off
from .energy import LearnedEnergy
from .collision import HingeCollision
from .bounds import Bounds
from .reach import ReachLimit
from .target import PoseTarget
from .effort import Anchor, Displacement, EffortTerm, MoveCount
from .function import CostFn
from .relation import Relation
from .examples import ExampleRelations

# isort: on

__all__ = [
    "Anchor",
    "Binding",
    "Bounds",
    "ConstraintCost",
    "Cost",
    "CostError",
    "CostFn",
    "CostSpec",
    "Displacement",
    "EffortTerm",
    "ExampleRelations",
    "Guide",
    "HingeCollision",
    "LearnedEnergy",
    "MoveCount",
    "PoseTarget",
    "ReachLimit",
    "Relation",
    "SpecContext",
    "Sum",
    "SymbolicProblem",
    "TermValue",
    "Verdict",
    "Violation",
    "as_sum",
    "cost_types",
    "register_casadi_form",
    "register_cost_type",
]
