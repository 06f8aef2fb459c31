"""scenescore: learn a cost function for object arrangement from examples, and plan with it."""

from __future__ import annotations

from . import costs, learn, models, planning, scenarios, solvers, workflow
from .encoders import Encoder, FootprintEncoder, make_encoder
from .models import load as load_model  # ss.load_model(path, device=...)
from .planning import place, tidy  # fill the null poses (`scenescore place`); tidy a messy scene
from .problem import Problem, ProblemError
from .runtime.threads import thread_budget  # with ss.thread_budget(1): ... is --threads 1
from .scene import Scene, SceneError, SceneObject, read_jsonl, write_jsonl
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
    "costs",
    "learn",
    "models",
    "planning",
    "solvers",
    "workflow",
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
