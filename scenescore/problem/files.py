"""YAML problem files: a typed schema, and errors that name the file, the line and the key path.

::

    scene: scene.json            # a path (relative to this file) or an inline scene mapping
    model: model.ckpt            # needed by an `energy` cost
    movable: [mug]               # optional; objects with pose null always move
    costs:
      - {type: energy, weight: 1.0}          # objects: [mug, plate_0] restricts what it sees
      - {type: collision, weight: 10.0, margin: 0.01}
      - {type: bounds}
      - {type: reach, base: [0.0, -0.5], radius: 0.8}
      - {type: target, object: mug, xy: [0.1, 0.2]}
      - {type: relation, model: left_of.ckpt, objects: [mug, plate_0]}   # a learned relation
    solver: langevin>osqp        # a solver or a chain
    options: {langevin: {particles: 64}, osqp: {max_iter: 50}}
    seed: 0

Each cost ``type`` is read by the spec its cost module registered (:func:`scenescore.costs.register_cost_type`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..costs import Cost, CostError, CostSpec, cost_types
from ..errors import nearest_name
from ..runtime import resolve_device
from ..scene.scene import Scene, SceneError
from ..scene.textfiles import MAX_DEPTH, check_yaml_depth, check_yaml_tree, read_text
from ..solvers import available, option_names
from ..solvers import get as get_solver
from ..solvers.registry import run_setting_note
from .problem import Problem, ProblemError

__all__ = ["ProblemSpec", "load_problem", "LoadedProblem"]

KeyPath = tuple[str | int, ...]


class ProblemSpec(BaseModel):
    """The typed schema of a YAML problem file (each cost is then read by its own registered spec)."""

    model_config = ConfigDict(extra="forbid")
    scene: str | dict[str, Any]
    model: str | None = None
    movable: list[str] | None = None
    costs: list[dict[str, Any]] = Field(min_length=1)
    solver: str = "langevin>osqp"
    options: dict[str, dict[str, Any]] = Field(default_factory=dict)
    seed: int = Field(0, ge=-(2**63), lt=2**63)


@dataclass
class LoadedProblem:
    """A problem read from YAML, with the solver settings it names."""

    problem: Problem
    solver: str
    options: dict[str, dict[str, Any]]
    seed: int
    spec: ProblemSpec
    path: Path | None
    costs: list[CostSpec]


def _lines(node: yaml.Node, path: KeyPath = (), out: dict[KeyPath, int] | None = None) -> dict[KeyPath, int]:
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


def _fmt(path: KeyPath) -> str:
    s = ""
    for p in path:
        s += f"[{p}]" if isinstance(p, int) else (f".{p}" if s else str(p))
    return s or "(top level)"


class _Where:
    """``where(path)``: ``file:line: key.path`` for error messages."""

    def __init__(self, source: str, lines: dict[KeyPath, int]):
        self.source, self.lines = source, lines

    def __call__(self, path: KeyPath) -> str:
        for k in range(len(path), -1, -1):
            if path[:k] in self.lines:
                return f"{self.source}:{self.lines[path[:k]]}: {_fmt(path)}"
        return f"{self.source}: {_fmt(path)}"


def _near(name: str, valid: list[str]) -> str:
    near = nearest_name(name, valid)
    return f"; did you mean {near!r}?" if near else ""


def _pydantic_error(
    e: ValidationError, where: _Where, model: type[BaseModel], prefix: KeyPath
) -> ProblemError:
    """The first error of ``e`` as one line naming the key path (a misspelt key explains the rest)."""
    errs = e.errors()
    err = next((x for x in errs if x["type"] == "extra_forbidden"), errs[0])
    path = (*prefix, *err["loc"])
    kind, msg = err["type"], err["msg"]
    if kind == "extra_forbidden":
        valid = sorted(model.model_fields)
        return ProblemError(
            f"{where(path)}: unknown key {path[-1]!r}{_near(str(path[-1]), valid)} (valid keys: {', '.join(valid)})"
        )
    if kind == "missing":
        return ProblemError(f"{where(path[:-1])}: missing key {path[-1]!r}")
    return ProblemError(f"{where(path)}: {msg} (got {err.get('input')!r})")


class _Context:
    """What cost specs ask of the file: object names checked against the scene, the model loaded once."""

    def __init__(self, scene: Scene, spec: ProblemSpec, root: Path, where: _Where, device: Any = None):
        self.scene, self.spec, self.root, self.where = scene, spec, root, where
        self.device = device  # where the model is loaded to
        self.at: KeyPath = ()
        self._model: Any = None
        self._checkpoints: dict[Path, Any] = {}  # resolved path -> model, so that terms share one

    def object(self, name: str, at: KeyPath) -> str:
        if name not in self.scene.names:
            raise ProblemError(
                f"{self.where((*self.at, *at))}: no object named {name!r} in the scene"
                f"{_near(name, self.scene.names)} (objects: {', '.join(self.scene.names)})"
            )
        return name

    def objects(self, names: list[str] | None, at: KeyPath) -> list[str] | None:
        return None if names is None else [self.object(n, (*at, i)) for i, n in enumerate(names)]

    def model(self, at: KeyPath) -> Any:
        if self.spec.model is None:
            raise ProblemError(
                f"{self.where(self.at)}: an 'energy' cost needs a 'model' (a checkpoint path) at the top level"
            )
        if self._model is None:
            self._model = self._load(self.spec.model, ("model",))
        return self._model

    def checkpoint(self, path: str, at: KeyPath) -> Any:
        mp = Path(path) if Path(path).is_absolute() else self.root / path
        key: Any = path if _shipped_name(path, mp) else mp.resolve()
        if key not in self._checkpoints:
            self._checkpoints[key] = self._load(path, (*self.at, *at))
        return self._checkpoints[key]

    def _load(self, path: str, at: KeyPath) -> Any:
        """The model at ``path`` (relative to the problem file), or, for a bare name (no folder, no
        extension) that is no file there, the package's pretrained model of that name (``dining``,
        ``relation-left_of``), as the command line reads a model argument."""
        from ..models import CheckpointError, load, pretrained

        mp = Path(path) if Path(path).is_absolute() else self.root / path
        if _shipped_name(path, mp):
            try:
                return pretrained(path, device=self.device)
            except CheckpointError as e:
                raise ProblemError(f"{self.where(at)}: {e}") from None
        if not mp.exists():
            raise ProblemError(
                f"{self.where(at)}: model checkpoint {str(mp)!r} does not exist "
                "(train one with `scenescore train DATA.jsonl --out MODEL.ckpt`)"
            )
        return load(mp, device=self.device)


def _shipped_name(path: str, resolved: Path) -> bool:
    """Whether a model key names a shipped model: a bare name (no folder, no extension), no file."""
    return not resolved.exists() and Path(path).name == path and not Path(path).suffix


def _cost_spec(entry: dict[str, Any], at: KeyPath, where: _Where) -> CostSpec:
    """One ``costs`` entry validated by the spec registered for its ``type``."""
    types = cost_types()
    kind = entry.get("type")
    if kind not in types:
        raise ProblemError(
            f"{where(at)}: cost 'type' must be one of {', '.join(types)} (got {kind!r})"
            + (_near(kind, list(types)) if isinstance(kind, str) else "")
        )
    model = types[kind]
    try:
        return model.model_validate(entry)
    except ValidationError as e:
        raise _pydantic_error(e, where, model, at) from None


def _check_solver_names(spec: ProblemSpec, where: _Where) -> None:
    """Every stage of ``solver`` exists; every ``options`` entry is for a stage of the chain, names
    options that solver has (the nearest one suggested) and holds values it accepts."""
    names = available()
    stages = [stage.strip() for stage in spec.solver.split(">")]
    for stage in spec.solver.split(">"):
        if stage.strip() not in names:
            raise ProblemError(
                f"{where(('solver',))}: unknown solver {stage!r}{_near(stage.strip(), names)} "
                f"(available: {', '.join(names)})"
            )
    for name, opts in spec.options.items():
        if name not in names:
            raise ProblemError(
                f"{where(('options', name))}: unknown solver {name!r}{_near(name, names)} "
                f"(available: {', '.join(names)})"
            )
        if name not in stages:
            raise ProblemError(
                f"{where(('options', name))}: options for solver {name!r}, which is not in the chain "
                f"{spec.solver!r}; they would be ignored (remove them, or add {name!r} to 'solver')"
            )
        valid = option_names(name)
        if valid is not None:
            for key in opts:
                if key not in valid:
                    raise ProblemError(
                        f"{where(('options', name, key))}: unknown option {key!r} for solver {name!r}"
                        f"{_near(str(key), valid)}{run_setting_note(str(key))} (valid: {', '.join(valid)})"
                    )
        try:
            get_solver(name, **opts)
        except ProblemError as e:
            bad = [k for k in opts if f": {k}:" in str(e)]
            at: KeyPath = ("options", name, *bad[:1])
            raise ProblemError(f"{where(at)}: {e}") from None


def load_problem(
    path: str | os.PathLike | None = None, text: str | None = None, device: str | torch.device | None = None
) -> LoadedProblem:
    """Read a YAML problem file (or ``text``); every error names the file, line and key path. ``device``
    (default the CPU): where its model is loaded to and its problem lives."""
    dev = resolve_device(device)
    p: Path | None
    if text is None:
        if path is None:
            raise ProblemError("load_problem: give a path or text")
        p = Path(path)
        text = read_text(p, ProblemError, "problem file")
        source, root = str(p), p.parent
    else:
        p = Path(path) if path else None
        source, root = str(path or "<problem>"), (p.parent if p else Path.cwd())
    try:
        check_yaml_depth(text, source, ProblemError)
        node = yaml.compose(text)
        if node is not None:  # bounded before anything expands the aliases
            check_yaml_tree(node, source, ProblemError)
        data = yaml.safe_load(text)
    except yaml.reader.ReaderError as e:  # a control character YAML does not allow in a file
        at = text[: e.position].count("\n") + 1
        raise ProblemError(
            f"{source}:{at}: not valid YAML: character {chr(e.character)!r} (#x{e.character:04x}) is not "
            "allowed in YAML"
        ) from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        at_line = f":{mark.line + 1}" if mark else ""
        what = " ".join(str(getattr(e, "problem", None) or e).split())  # one line
        raise ProblemError(f"{source}{at_line}: not valid YAML: {what}") from None
    except RecursionError:
        raise ProblemError(f"{source}: YAML nested deeper than {MAX_DEPTH} levels") from None
    if not isinstance(data, dict) or node is None:
        raise ProblemError(
            f"{source}: expected a mapping with 'scene' and 'costs', got {type(data).__name__}"
        )
    where = _Where(source, _lines(node))
    try:
        spec = ProblemSpec.model_validate(data)
    except ValidationError as e:
        raise _pydantic_error(e, where, ProblemSpec, ()) from None
    specs = [_cost_spec(c, ("costs", k), where) for k, c in enumerate(spec.costs)]

    if isinstance(spec.scene, str):
        sp = Path(spec.scene) if Path(spec.scene).is_absolute() else root / spec.scene
        if not sp.exists():
            raise ProblemError(f"{where(('scene',))}: scene file {str(sp)!r} does not exist")
        scene = Scene.from_json(sp)
    else:
        try:
            scene = Scene.from_dict(spec.scene, source=f"{where(('scene',))}")
        except SceneError as e:
            raise ProblemError(str(e)) from None

    ctx = _Context(scene, spec, root, where, dev)
    terms: list[Cost] = []
    for k, cs in enumerate(specs):
        ctx.at = ("costs", k)
        try:
            terms.append(cs.weight * cs.build(ctx))
        except CostError as e:
            raise ProblemError(f"{where(ctx.at)}: {e}") from None
    ctx.at = ()
    movable = ctx.objects(spec.movable, ("movable",))
    try:
        cost = sum(terms[1:], terms[0])
        problem = Problem(scene, cost, movable=movable, name=p.stem if p else "problem", device=dev)
    except (CostError, SceneError) as e:
        raise ProblemError(f"{where(('costs',))}: {e}") from None
    except ProblemError as e:
        raise ProblemError(f"{where(('movable',))}: {e}") from None
    _check_solver_names(spec, where)
    return LoadedProblem(problem, spec.solver, spec.options, spec.seed, spec, p, specs)
