"""Composable costs: named, batched, differentiable terms that sum into one objective.

``ss.costs.LearnedEnergy(model) + 10.0 * ss.costs.HingeCollision(margin=0.01)`` is a flat weighted
:class:`Sum`; ``sum.terms(poses)`` gives every term's value, weight, weighted value and violation.
"""

from .base import Binding, ConstraintCost, Cost, CostError, Sum, TermValue, as_sum
from .geometry import Footprints, footprint_core, signed_distance
from .terms import Bounds, CostFn, HingeCollision, LearnedEnergy, PoseTarget, ReachLimit

__all__ = [
    "Binding",
    "Bounds",
    "ConstraintCost",
    "Cost",
    "CostError",
    "CostFn",
    "Footprints",
    "HingeCollision",
    "LearnedEnergy",
    "PoseTarget",
    "ReachLimit",
    "Sum",
    "TermValue",
    "as_sum",
    "footprint_core",
    "signed_distance",
]
