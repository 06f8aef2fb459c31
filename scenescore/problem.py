"""Problems: a scene, a cost, and which objects move; and YAML problem files.

``Problem(scene, cost, movable=["mug"])`` binds the cost to the scene. Objects with ``pose: null`` are
always movable (the first solver stage initialises them); fixed objects never are. With ``movable=None``
the unknown objects move if there are any, else every object that is not fixed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from .costs import Bounds, Cost, HingeCollision, ReachLimit, Sum, as_sum
from .costs.exact import overlap_depth_exceeds, shapely_core
from .costs.geometry import footprint_core
from .scene import Scene, SceneError

__all__ = ["Problem", "ProblemError", "Feasibility"]

FEASIBILITY_TOL = 1e-4  # metres: the largest violation that still counts as feasible


class ProblemError(ValueError):
    """A problem that cannot be set up: bad YAML, an unknown object, a missing file; one line for the user."""


@dataclass
class Feasibility:
    """The exact check of a pose set: overlapping pairs (shapely), objects out of bounds or reach."""

    feasible: bool
    collisions: list[tuple[str, str, float]] = field(default_factory=list)  # (a, b, exact signed distance)
    out_of_bounds: list[tuple[str, float]] = field(default_factory=list)
    out_of_reach: list[tuple[str, float]] = field(default_factory=list)

    def describe(self) -> str:
        parts = [
            f"{a} overlaps {b} ({-d * 1000:.2f} mm)"
            if d < 0
            else f"{a} within margin of {b} ({d * 1000:.2f} mm apart)"
            for a, b, d in self.collisions
        ]
        parts += [f"{n} out of bounds by {v * 1000:.2f} mm" for n, v in self.out_of_bounds]
        parts += [f"{n} out of reach by {v * 1000:.2f} mm" for n, v in self.out_of_reach]
        return "; ".join(parts) if parts else "feasible"


class Problem:
    """A scene, a cost bound to it, and the objects that may move."""

    def __init__(self, scene: Scene, cost: Cost, movable: Sequence[str] | None = None, name: str = "problem"):
        if not isinstance(scene, Scene):
            raise ProblemError(f"Problem: expected a scenescore Scene, got {type(scene).__name__}")
        self.scene = scene
        self.name = name
        unknown = set(scene.unknown)
        if movable is None:
            names = list(scene.unknown) or [o.name for o in scene.objects if not o.fixed]
        else:
            if isinstance(movable, str):
                movable = [movable]
            names = list(movable)
            for n in names:
                try:
                    scene.index(n)
                except SceneError:
                    raise ProblemError(f"movable: no object named {n!r}; objects are {scene.names}") from None
            names += [n for n in scene.unknown if n not in names]
        for n in names:
            if scene[n].fixed:
                raise ProblemError(f'movable: object {n!r} is fixed ("fixed": true) and can never move')
        if not names:
            raise ProblemError(
                "Problem: no object may move (every object is fixed or has a known pose and none is listed)"
            )
        self.movable_mask = np.array([o.name in names for o in scene.objects])
        self.known = np.array([o.name not in unknown for o in scene.objects])
        self.cost: Sum = as_sum(cost).bind(scene, self.movable_mask)

    # -- shapes and bounds -----------------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.scene)

    @property
    def movable(self) -> list[str]:
        return [o.name for o, m in zip(self.scene.objects, self.movable_mask) if m]

    @property
    def lo(self) -> Tensor:
        return torch.tensor(self.scene.bounds[0], dtype=torch.float64)

    @property
    def hi(self) -> Tensor:
        return torch.tensor(self.scene.bounds[1], dtype=torch.float64)

    def base_poses(self) -> Tensor:
        """The scene's poses ``(N, 3)`` (unknown ones 0), float64."""
        return torch.tensor(self.scene.poses(), dtype=torch.float64)

    def initial(self, particles: int, generator: torch.Generator, keep_known: bool = False) -> Tensor:
        """Initial particles ``(B, N, 3)``: moving objects uniform in the bounds (``keep_known``: only unknown ones)."""
        from .solvers.langevin import uniform_init

        x = self.base_poses()[None].repeat(particles, 1, 1)
        u = uniform_init((particles, self.n), self.lo, self.hi, generator, dtype=torch.float64)
        draw = self.movable_mask & (~self.known if keep_known else True)
        mask = torch.as_tensor(draw)[None, :, None]
        return torch.where(mask, u, x)

    def full(self, poses: Tensor | np.ndarray) -> Tensor:
        """Poses as ``(B, N, 3)`` float64; a single ``(N, 3)`` pose set is given a batch of 1. Checks shapes."""
        x = torch.as_tensor(
            np.asarray(poses) if not isinstance(poses, Tensor) else poses, dtype=torch.float64
        )
        if x.dim() == 2:
            x = x[None]
        if x.dim() != 3 or x.shape[1:] != (self.n, 3):
            raise ProblemError(
                f"init: expected poses of shape (N, 3) or (B, N, 3) with N = {self.n}, got {tuple(x.shape)}"
            )
        if not torch.isfinite(x).all():
            raise ProblemError("init: poses contain NaN or inf")
        return x

    # -- evaluation --------------------------------------------------------------------------------
    def evaluate(self, poses: Tensor) -> Tensor:
        """The total cost ``(B,)``."""
        return self.cost(self.full(poses))

    def violation(self, poses: Tensor) -> Tensor:
        """The largest constraint violation per row ``(B,)`` (0 when the cost has no constraint)."""
        v = self.cost.violation(self.full(poses))
        return torch.zeros(self.full(poses).shape[0], dtype=torch.float64) if v is None else v

    def check(self, poses: np.ndarray | Tensor, tol: float = FEASIBILITY_TOL) -> Feasibility:
        """The exact check (shapely) of one pose set ``(N, 3)`` against the cost's constraints, within ``tol`` m."""
        p = np.asarray(self.full(poses)[0])
        objs = self.scene.objects
        geo = {}

        def g(i: int):
            if i not in geo:
                geo[i] = shapely_core(objs[i], p[i])
            return geo[i]

        out = Feasibility(True)
        for c in self.cost.constraint_terms:
            if isinstance(c, HingeCollision):
                for i, j in c.support():
                    (ca, ra), (cb, rb) = g(i), g(j)
                    if overlap_depth_exceeds((ca, ra), (cb, rb), tol):
                        d = float(c.signed_distance(torch.as_tensor(p)[None])[0, c.support().index((i, j))])
                        out.collisions.append((objs[i].name, objs[j].name, d))
                    elif c.margin > tol:
                        d = ca.distance(cb) - ra - rb
                        if d < c.margin - tol:
                            out.collisions.append((objs[i].name, objs[j].name, d))
            elif isinstance(c, Bounds):
                lo, hi = c._lo.numpy(), c._hi.numpy()
                for i in c._idx:
                    if c.footprint:
                        core, r = footprint_core(objs[i])
                        ca, _ = g(i)
                        x0, y0, x1, y1 = ca.bounds
                        mn, mx = np.array([x0 - r, y0 - r]), np.array([x1 + r, y1 + r])
                    else:
                        mn = mx = p[i, :2]
                    v = float(max(np.max(lo - mn), np.max(mx - hi), 0.0))
                    if v > tol:
                        out.out_of_bounds.append((objs[i].name, v))
            elif isinstance(c, ReachLimit):
                for i in c._idx:
                    v = float(np.hypot(*(p[i, :2] - np.array(c.base))) - c.radius)
                    if v > tol:
                        out.out_of_reach.append((objs[i].name, v))
        out.feasible = not (out.collisions or out.out_of_bounds or out.out_of_reach)
        return out

    def __repr__(self) -> str:
        return f"Problem({self.name!r}, {self.n} objects, movable={self.movable}, cost={self.cost!r})"


# ---------------------------------------------------------------------------------------------------
# YAML problem files
# ---------------------------------------------------------------------------------------------------
#
#   scene: scene.json            # a path (relative to this file) or an inline scene mapping
#   model: model.ckpt            # needed by an `energy` cost
#   movable: [mug]               # optional; objects with pose null always move
#   costs:
#     - {type: energy, weight: 1.0}          # objects: [mug, plate_0] restricts what it sees
#     - {type: collision, weight: 10.0, margin: 0.01}
#     - {type: bounds}
#     - {type: reach, base: [0.0, -0.5], radius: 0.8}
#     - {type: target, object: mug, xy: [0.1, 0.2]}
#   solver: langevin>osqp        # a solver or a chain
#   options: {langevin: {particles: 64}, osqp: {max_iter: 50}}
#   seed: 0

import difflib  # noqa: E402
import os  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Annotated, Any, Literal  # noqa: E402

import yaml  # noqa: E402
from pydantic import BaseModel, ConfigDict, Field, ValidationError  # noqa: E402

__all__ += ["ProblemSpec", "load_problem", "LoadedProblem"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class EnergySpec(_Strict):
    type: Literal["energy"]
    weight: float = Field(1.0, ge=0)
    objects: list[str] | None = None  # the objects the energy sees (default: all)
    name: str | None = None


class CollisionSpec(_Strict):
    type: Literal["collision"]
    weight: float = Field(1.0, ge=0)
    margin: float = Field(0.0, ge=0)
    pairs: Literal["all"] | list[tuple[str, str]] = "all"
    power: Literal[1, 2] = 1
    name: str | None = None


class BoundsSpec(_Strict):
    type: Literal["bounds"]
    weight: float = Field(1.0, ge=0)
    lo: tuple[float, float] | None = None
    hi: tuple[float, float] | None = None
    footprint: bool = True
    objects: list[str] | None = None
    name: str | None = None


class ReachSpec(_Strict):
    type: Literal["reach"]
    weight: float = Field(1.0, ge=0)
    base: tuple[float, float]
    radius: float = Field(gt=0)
    objects: list[str] | None = None
    name: str | None = None


class TargetSpec(_Strict):
    type: Literal["target"]
    weight: float = Field(1.0, ge=0)
    object: str
    xy: tuple[float, float]
    theta: float | None = None
    name: str | None = None


CostSpec = Annotated[
    EnergySpec | CollisionSpec | BoundsSpec | ReachSpec | TargetSpec, Field(discriminator="type")
]
_COST_MODELS = {
    "energy": EnergySpec,
    "collision": CollisionSpec,
    "bounds": BoundsSpec,
    "reach": ReachSpec,
    "target": TargetSpec,
}


class ProblemSpec(_Strict):
    """The typed schema of a YAML problem file."""

    scene: str | dict[str, Any]
    model: str | None = None
    movable: list[str] | None = None
    costs: list[CostSpec] = Field(min_length=1)
    solver: str = "langevin>osqp"
    options: dict[str, dict[str, Any]] = Field(default_factory=dict)
    seed: int = 0


@dataclass
class LoadedProblem:
    """A problem read from YAML, with the solver settings it names."""

    problem: Problem
    solver: str
    options: dict[str, dict[str, Any]]
    seed: int
    spec: ProblemSpec
    path: Path | None


def _lines(node, path=(), out=None) -> dict[tuple, int]:
    """Key path -> line number (1-based) of every mapping key and sequence item in a composed YAML node."""
    out = {} if out is None else out
    out.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            p = (*path, k.value)
            out[p] = k.start_mark.line + 1
            _lines(v, p, out)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            _lines(v, (*path, i), out)
    return out


def _fmt(path: tuple) -> str:
    s = ""
    for p in path:
        s += f"[{p}]" if isinstance(p, int) else (f".{p}" if s else str(p))
    return s or "(top level)"


class _Where:
    def __init__(self, source: str, lines: dict[tuple, int]):
        self.source, self.lines = source, lines

    def __call__(self, path: tuple) -> str:
        for k in range(len(path), -1, -1):
            if path[:k] in self.lines:
                return f"{self.source}:{self.lines[path[:k]]}: {_fmt(path)}"
        return f"{self.source}: {_fmt(path)}"


def _pydantic_error(e: ValidationError, where: _Where, data: Any) -> ProblemError:
    errs = e.errors()
    err = next(
        (x for x in errs if x["type"] == "extra_forbidden"), errs[0]
    )  # a misspelt key explains the rest
    loc = list(err["loc"])
    # a discriminated union puts the tag in the path: costs.1.collision.margin -> costs[1].margin
    if len(loc) >= 3 and loc[0] == "costs" and isinstance(loc[1], int) and loc[2] in _COST_MODELS:
        model = _COST_MODELS[loc.pop(2)]
    elif loc and loc[0] == "costs" and len(loc) >= 2:
        model = None
    else:
        model = ProblemSpec
    path = tuple(loc)
    kind, msg = err["type"], err["msg"]
    if kind == "extra_forbidden":
        valid = sorted(model.model_fields) if model else []
        near = difflib.get_close_matches(str(path[-1]), valid, n=1)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        return ProblemError(f"{where(path)}: unknown key {path[-1]!r}{hint} (valid keys: {', '.join(valid)})")
    if kind == "missing":
        return ProblemError(f"{where(path[:-1])}: missing key {path[-1]!r}")
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        return ProblemError(f"{where(path)}: cost 'type' must be one of {', '.join(_COST_MODELS)} ({msg})")
    got = err.get("input")
    return ProblemError(f"{where(path)}: {msg} (got {got!r})")


def load_problem(path: str | os.PathLike | None = None, text: str | None = None) -> LoadedProblem:
    """Read a YAML problem file (or ``text``); every error names the file, line and key path."""
    if text is None:
        if path is None:
            raise ProblemError("load_problem: give a path or text")
        p = Path(path)
        if not p.exists():
            raise ProblemError(f"{p}: no such problem file")
        text = p.read_text()
        source, root = str(p), p.parent
    else:
        source, root, p = (
            str(path or "<problem>"),
            Path(path).parent if path else Path.cwd(),
            Path(path) if path else None,
        )
    try:
        node = yaml.compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f":{mark.line + 1}" if mark else ""
        raise ProblemError(f"{source}{line}: not valid YAML: {getattr(e, 'problem', e)}") from None
    if not isinstance(data, dict):
        raise ProblemError(
            f"{source}: expected a mapping with 'scene' and 'costs', got {type(data).__name__}"
        )
    where = _Where(source, _lines(node))
    try:
        spec = ProblemSpec.model_validate(data)
    except ValidationError as e:
        raise _pydantic_error(e, where, data) from None

    # the scene
    if isinstance(spec.scene, str):
        sp = (root / spec.scene) if not Path(spec.scene).is_absolute() else Path(spec.scene)
        if not sp.exists():
            raise ProblemError(f"{where(('scene',))}: scene file {str(sp)!r} does not exist")
        scene = Scene.from_json(sp)
    else:
        try:
            scene = Scene.from_dict(spec.scene, source=f"{where(('scene',))}")
        except SceneError as e:
            raise ProblemError(str(e)) from None

    def obj(name: str, at: tuple) -> str:
        if name not in scene.names:
            near = difflib.get_close_matches(name, scene.names, n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ProblemError(
                f"{where(at)}: no object named {name!r} in the scene{hint} (objects: {', '.join(scene.names)})"
            )
        return name

    from . import costs as C

    model = None
    terms: list[Cost] = []
    for k, c in enumerate(spec.costs):
        at = ("costs", k)
        kw = {"name": c.name} if c.name else {}
        if isinstance(c, EnergySpec):
            if spec.model is None:
                raise ProblemError(
                    f"{where(at)}: an 'energy' cost needs a 'model' (a checkpoint path) at the top level"
                )
            if model is None:
                mp = (root / spec.model) if not Path(spec.model).is_absolute() else Path(spec.model)
                if not mp.exists():
                    raise ProblemError(f"{where(('model',))}: model checkpoint {str(mp)!r} does not exist")
                from .models import load

                model = load(mp)
            if c.objects is not None:
                kw["objects"] = [obj(nm, (*at, "objects", i)) for i, nm in enumerate(c.objects)]
            term: Cost = C.LearnedEnergy(model, **kw)
        elif isinstance(c, CollisionSpec):
            pairs = (
                c.pairs
                if c.pairs == "all"
                else [
                    [obj(a, (*at, "pairs", i)), obj(b, (*at, "pairs", i))] for i, (a, b) in enumerate(c.pairs)
                ]
            )
            term = C.HingeCollision(margin=c.margin, pairs=pairs, power=c.power, **kw)
        elif isinstance(c, BoundsSpec):
            objs = (
                None if c.objects is None else [obj(n, (*at, "objects", i)) for i, n in enumerate(c.objects)]
            )
            term = C.Bounds(lo=c.lo, hi=c.hi, footprint=c.footprint, objects=objs, **kw)
        elif isinstance(c, ReachSpec):
            objs = (
                None if c.objects is None else [obj(n, (*at, "objects", i)) for i, n in enumerate(c.objects)]
            )
            term = C.ReachLimit(base=c.base, radius=c.radius, objects=objs, **kw)
        else:
            term = C.PoseTarget(obj(c.object, (*at, "object")), c.xy, c.theta, **kw)
        terms.append(c.weight * term)
    movable = None if spec.movable is None else [obj(n, ("movable", i)) for i, n in enumerate(spec.movable)]
    try:
        cost = sum(terms[1:], terms[0])
        problem = Problem(scene, cost, movable=movable, name=p.stem if p else "problem")
    except (C.CostError, SceneError) as e:
        raise ProblemError(f"{where(('costs',))}: {e}") from None
    except ProblemError as e:
        raise ProblemError(f"{where(('movable',))}: {e}") from None
    from .solvers import available

    for stage in spec.solver.split(">"):
        if stage.strip() not in available():
            near = difflib.get_close_matches(stage.strip(), available(), n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ProblemError(
                f"{where(('solver',))}: unknown solver {stage!r}{hint} (available: {', '.join(available())})"
            )
    for name in spec.options:
        if name not in available():
            near = difflib.get_close_matches(name, available(), n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ProblemError(
                f"{where(('options', name))}: unknown solver {name!r}{hint} (available: {', '.join(available())})"
            )
    return LoadedProblem(problem, spec.solver, spec.options, spec.seed, spec, p)
