"""Tidying a messy scene: a desirable arrangement reached with little robot effort, and the order of moves.

Every known pose is the current state. :func:`tidy` minimises the learned energy plus the effort of
moving objects from where they are (:class:`~scenescore.costs.Displacement` and
:class:`~scenescore.costs.MoveCount`), with non-overlap, bounds and, when given, reach:

1. *Selection*: a forward selection of the objects to move, with a backward check. Each step re-places
   the objects chosen so far together with one more movable object (placed by the learned energy with
   the others where they are; as many draws as placement screens for the bounds, half of them proposed
   beside the objects that stay as the data has them; half keep the chosen objects where the last step
   put them, an eighth start near where the set's objects are, a quarter put two of the set in each
   other's places; every candidate set of every scene in one batched chain per size; the exact
   exchanges of two of the set are candidates too) and keeps the set whose best placement lowers the
   whole cost most; then each chosen object is tried back where it is, the rest re-placed. Each step
   also tries the pairs of objects of different kinds whose exchange lowers the cost most (a swap,
   where a false single move may pay first). When no single object pays, pairs of the best single
   candidates are tried together (two objects each where the other belongs). It stops when nothing
   lowers the cost. Moving an object costs, at effort 1, what re-placing an object of a
   right scene gains by the model's noise (:func:`calibrate`, :func:`count_weight`), times the object's
   effort weight: larger objects than the scene's median cost more (:func:`effort_weights`), so where
   moving either end of a relation fixes it, the smaller one moves.
2. *Pruning*: objects that moved less than ``move_tol`` go back to where they are; each remaining move
   is undone when that lowers the cost; the moved objects are also placed again by the missing-object
   placement, and so is each set of them one smaller (the left-out object where it is); the candidate
   with the lowest whole cost is kept, and a last refinement (``osqp``) runs over its moved objects
   alone, so every other object is exactly where it was. For one scene on a machine with a core to
   spare, that placement of the set chosen so far starts on the second core while the selection goes
   on (:mod:`.pipeline`; the same answer to the bit).

:func:`plan_moves` then orders the moves so that each target is free of every object still in place
when the object is put down (the exact check), parking an object at a buffer pose where the moves
depend on each other in a cycle (two objects swapping places); :func:`validate_plan` replays a plan.

The package, one module per stage: :mod:`.types` (settings, result, plan step, error, default weights),
:mod:`.problem` (the problem, effort weights, the cost of a move), :mod:`.draws` and :mod:`.selection`
(stage 1), :mod:`.calibration` (what a move must gain), :mod:`.pruning` (stage 2), :mod:`.plan` (the
pick-and-place plan) and :mod:`.pipeline` (the stages in order: :func:`tidy`, :func:`tidy_many`).
"""

from __future__ import annotations

from .calibration import calibrate
from .pipeline import tidy, tidy_many
from .plan import plan_moves, validate_plan
from .problem import count_weight, effort_weights
from .types import EFFORT, PlanCheck, Reach, Request, Step, TidyError, TidyOptions, TidyResult

__all__ = [
    "EFFORT",
    "PlanCheck",
    "Reach",
    "Request",
    "Step",
    "TidyError",
    "TidyOptions",
    "TidyResult",
    "calibrate",
    "count_weight",
    "effort_weights",
    "plan_moves",
    "tidy",
    "tidy_many",
    "validate_plan",
]
