"""scenescore: learn a cost function for object arrangement from examples, and plan with it."""

from __future__ import annotations

from . import costs, models, scenarios, solvers
from .encoders import Encoder, FootprintEncoder, make_encoder
from .models import load as load_model  # ss.load_model(path, device=...)
from .planning.placement import (
    place,  # ss.place(model, scene, seed=0): fill the null poses, as `scenescore place`
)
from .planning.tidying import (
    tidy,  # ss.tidy(model, scene, effort=1.0, seed=0); the package: scenescore.planning.tidying
)
from .problem.problem import Problem, ProblemError
from .runtime.threads import thread_budget  # with ss.thread_budget(1): ... is --threads 1
from .scene.scene import Scene, SceneError, SceneObject, read_jsonl, write_jsonl
from .solvers import solve
from .workflow import train  # ss.train(scenes, seed=0): `scenescore train`'s model

__version__ = "0.1.0"

__all__ = [
    "Encoder",
    "FootprintEncoder",
    "make_encoder",
    "Scene",
    "SceneError",
    "SceneObject",
    "read_jsonl",
    "write_jsonl",
    "models",
    "costs",
    "solvers",
    "Problem",
    "ProblemError",
    "solve",
    "thread_budget",
    "tidy",
    "train",
    "load_model",
    "place",
    "scenarios",
]
