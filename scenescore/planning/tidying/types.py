"""What tidying takes and gives: its settings, its result, a pick-and-place step, a replayed plan's
verdict, its error, and the default weights."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, cast

from ...errors import ConfigError, check_number
from ...problem.problem import ProblemError
from ...scene.outputs import atomic_write_text
from ...scene.scene import Scene
from ...solvers import Result
from ...solvers.kernel import PLACEMENT
from ...solvers.langevin import LangevinOptions

__all__ = [
    "EFFORT",
    "Request",
    "COUNT",
    "GAIN_QUANTILE",
    "Reach",
    "TidyError",
    "TidyOptions",
    "Step",
    "PlanCheck",
    "TidyResult",
]

#: the default effort weight: multiplies the count and displacement weights of :class:`TidyOptions`
EFFORT = 1.0
#: energy per moved object when the model has no calibrated move gain (:func:`calibrate`)
COUNT = 0.3
#: the chance that noise alone moves none of a right scene's objects (:func:`calibrate`, :func:`count_weight`)
GAIN_QUANTILE = 0.75


Reach = tuple[tuple[float, float], float]  # ((x, y) of the robot's base, radius in metres)


@dataclass(frozen=True)
class Request:
    """What a tidy is asked beside the scene: how much the robot's effort weighs (``effort``), the
    objects that must not move (``stay``), each object's effort weight (``weights``, heavy or fragile:
    more) and the robot's ``reach``."""

    effort: float = EFFORT
    stay: Sequence[str] = ()
    weights: dict[str, float] | None = None
    reach: Reach | None = None


class TidyError(ProblemError):
    """A scene that cannot be tidied or a plan that cannot be made; one line naming the object."""


@dataclass(frozen=True)
class TidyOptions:
    """Settings of :func:`tidy` (the effort weight is an argument of its own)."""

    # at effort 1: energy per moved object (the smooth count's weight); None: the model's calibrated
    # move gain (:func:`calibrate`, stored in the checkpoint), else COUNT
    count: float | None = None
    distance: float = 0.1  # at effort 1: energy per length scale of displacement
    delta: float = 0.1  # length scales: the displacement is quadratic within this, then linear
    sigma: float = 0.05  # length scales: a move this long counts as half a moved object
    move_tol: float = 0.1  # length scales: an object that moved less than this stays where it is
    max_moves: int | None = None  # objects the forward selection may add (None: every movable one)
    gain_tol: float = 1e-6  # a step of the selection must lower the whole cost by more than this
    propose: LangevinOptions = LangevinOptions(
        particles=16, candidates=256, proposals=0.5, chain=replace(PLACEMENT, steps=40, final_descent=10)
    )
    refine: str | None = "osqp"  # the refinement of the moved objects after pruning (None: none)
    # the moved objects (and each set of them one smaller) also placed again by the missing-object
    # placement; the candidate with the lowest whole cost is kept
    place: bool = True
    refine_options: dict[str, Any] = field(default_factory=lambda: {"max_iter": 40})
    # objects larger than the scene's median one cost more to move (:func:`effort_weights`): where moving
    # either end of a relation fixes it, the smaller object is the one moved
    by_size: bool = True

    def __post_init__(self) -> None:
        own = "TidyOptions"
        if self.count is not None:
            check_number(own, "count", self.count, 0.0, math.inf)
        check_number(own, "distance", self.distance, 0.0, math.inf)
        for k in ("delta", "sigma", "move_tol"):
            check_number(own, k, getattr(self, k), 0.0, math.inf, open_lo=True)
        if self.max_moves is not None:
            check_number(own, "max_moves", self.max_moves, 0, 1_000_000, integer=True)
        check_number(own, "gain_tol", self.gain_tol, 0.0, math.inf)
        for k in ("place", "by_size"):
            if not isinstance(getattr(self, k), bool):
                raise ConfigError(f"TidyOptions: {k}: expected true or false, got {getattr(self, k)!r}")


@dataclass
class Step:
    """One pick-and-place: ``name`` from ``start`` (``None``: brought in) to ``goal``; ``buffer``: a parking move."""

    name: str
    start: tuple[float, float, float] | None
    goal: tuple[float, float, float]
    buffer: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {
            "object": self.name,
            "from": None if self.start is None else [float(v) for v in self.start],
            "to": [float(v) for v in self.goal],
            "kind": "buffer" if self.buffer else "target",
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Step:
        start = d.get("from")
        return cls(
            str(d["object"]),
            None if start is None else cast(tuple[float, float, float], tuple(float(v) for v in start)),
            cast(tuple[float, float, float], tuple(float(v) for v in d["to"])),
            d.get("kind") == "buffer",
        )


@dataclass
class PlanCheck:
    """A replayed plan: valid when every step was legal and every object ended at its target."""

    valid: bool
    problems: list[str] = field(default_factory=list)

    def describe(self) -> str:
        return "valid" if self.valid else "; ".join(self.problems)


@dataclass
class TidyResult:
    """What :func:`tidy` found: the current and the tidy scene, who moves, how far, and in what order."""

    before: Scene
    after: Scene
    moved: list[str]
    distance: dict[str, float]  # metres each object's centre travels (moved objects)
    turn: dict[str, float]  # radians each moved object turns (0 for round objects)
    displacement: dict[str, float]  # the effort's d_i: centre and tip together, metres
    steps: list[Step]
    check: PlanCheck
    result: Result
    effort: float
    seed: int
    warnings: list[str] = field(default_factory=list)
    count: float = 0.0  # energy one moved object costs (the count weight times the effort)

    @property
    def total_displacement(self) -> float:
        """Sum of the moved objects' displacements ``d_i`` (metres)."""
        return float(sum(self.displacement.values()))

    @property
    def total_distance(self) -> float:
        """Sum of the distances the moved objects' centres travel (metres)."""
        return float(sum(self.distance.values()))

    @property
    def plan_made(self) -> bool:
        """Whether a plan could be made (False: a target admits none; the reason is in ``check``)."""
        return self.check.valid or bool(self.steps)

    @property
    def buffers(self) -> int:
        return sum(s.buffer for s in self.steps)

    def to_dict(self) -> dict[str, Any]:
        objects = {}
        for o, a in zip(self.before.objects, self.after.objects):
            objects[o.name] = {
                "moves": o.name in self.moved,
                "from": None if o.pose is None else [float(v) for v in o.pose],
                "to": None if a.pose is None else [float(v) for v in a.pose],
                "distance": self.distance.get(o.name, 0.0),
                "turn": self.turn.get(o.name, 0.0),
                "displacement": self.displacement.get(o.name, 0.0),
            }
        r = self.result
        return {
            "effort": self.effort,
            "move_cost": self.count,
            "seed": self.seed,
            "moved": list(self.moved),
            "total_displacement": self.total_displacement,
            "total_distance": self.total_distance,
            "objects": objects,
            "plan": {
                "steps": [s.to_dict() for s in self.steps],
                "buffers": self.buffers,
                "valid": self.check.valid,
                "problems": self.check.problems,
            },
            "solve": {
                "solver": r.solver,
                "status": r.status.value,
                "feasible": r.feasible,
                "objective": r.objective,
                "terms": {k: t["weighted"] for k, t in r.terms.items()},
            },
            "warnings": list(self.warnings),
            "scene": self.after.to_dict(),
        }

    def to_json(self, path: str | os.PathLike | None = None) -> str:
        """The result as JSON; written atomically to ``path`` when given."""
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            atomic_write_text(path, text + "\n")
        return text
