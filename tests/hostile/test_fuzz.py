"""Property-based fuzzing of the scene JSON and YAML problem schemas: random and mutated documents either
load or raise the library's ``ValueError`` subclass with a one-line message, never another exception.
A scene that loads can be written and read back unchanged."""

from __future__ import annotations

import copy
import json
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from scenescore.costs import CostError
from scenescore.errors import ConfigError
from scenescore.models import CheckpointError
from scenescore.problem.files import load_problem
from scenescore.problem.problem import ProblemError
from scenescore.scene.scene import Scene, SceneError

from .helpers import SCENE

LIBRARY_ERRORS = (SceneError, ProblemError, CostError, ConfigError, CheckpointError)
FUZZ = settings(
    max_examples=120,  # about 1 s for a scene test, 5 s for a problem test (FUZZ_PROBLEMS) on one thread
    deadline=None,
    derandomize=True,  # the same examples on every run: a CI failure reproduces
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)

# numbers a hostile file would hold: the edges of float32 and float64, non-finite, huge integers
NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -0.0, 1e-300, 1e-45, 3.5e38, 1e39, 1e300, -1e20, 2**63, -(2**64), 255, 256, 0.5]),
    st.integers(min_value=-(2**70), max_value=2**70),
)
SCALARS = st.one_of(st.none(), st.booleans(), NUMBERS, st.text(max_size=12))
JSONISH = st.recursive(
    SCALARS,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)
OBJECT_KEYS = ["name", "category", "size", "pose", "color", "fixed", "shape", "features", "image", "extra"]
SCENE_KEYS = ["objects", "bounds", "meta", "walls"]


def _paths(doc: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _paths(v, (*prefix, i))
    return out


@st.composite
def mutated(draw: st.DrawFn, base: dict, keys: list[str]) -> Any:
    """``base`` with a few random edits: a value replaced, a key deleted or added, a list item dropped or
    duplicated, a polygon shape swapped in."""
    doc = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 4))):
        paths = _paths(doc)
        path = draw(st.sampled_from(paths))
        parent = doc
        for p in path[:-1]:
            parent = parent[p]
        op = draw(st.sampled_from(["replace", "delete", "add", "duplicate", "polygon"]))
        if not path:
            if op == "replace":
                doc = draw(JSONISH)
            continue
        key = path[-1]
        if op == "replace":
            parent[key] = draw(JSONISH)
        elif op == "delete":
            del parent[key]
        elif op == "add" and isinstance(parent, dict):
            parent[draw(st.sampled_from(keys))] = draw(JSONISH)
        elif op == "duplicate" and isinstance(parent, list):
            parent.append(copy.deepcopy(parent[key]))
        elif op == "polygon" and isinstance(parent, dict):
            pts = draw(st.lists(st.lists(NUMBERS, min_size=2, max_size=2), min_size=0, max_size=6))
            parent["shape"] = {"polygon": pts}
        if not isinstance(doc, (dict, list)):
            break
    return doc


def _check_message(e: Exception) -> None:
    msg = str(e)
    assert msg.strip() and "\n" not in msg.strip(), repr(msg)


@FUZZ
@given(mutated(SCENE, OBJECT_KEYS + SCENE_KEYS))
def test_scene_documents(doc):
    try:
        s = Scene.from_dict(doc, source="fuzz.json")
    except LIBRARY_ERRORS as e:
        _check_message(e)
        return
    # what loads can be written and read back unchanged
    again = Scene.from_dict(json.loads(s.to_json()), source="again.json")
    assert again == s


@FUZZ
@given(st.data())
def test_scene_files_mutated_as_text(tmp_path_factory, data):
    """The text of a valid scene with bytes cut, inserted or replaced, read from a file."""
    text = json.dumps(SCENE).encode()
    for _ in range(data.draw(st.integers(1, 3))):
        i = data.draw(st.integers(0, len(text)))
        j = data.draw(st.integers(i, min(len(text), i + 8)))
        text = text[:i] + data.draw(st.binary(max_size=6)) + text[j:]
    p = tmp_path_factory.mktemp("fuzz") / "s.json"
    p.write_bytes(text)
    try:
        Scene.from_json(p)
    except LIBRARY_ERRORS as e:
        _check_message(e)


FUZZ_PROBLEMS = settings(FUZZ, max_examples=80)  # each loads costs and builds solvers: slower

PROBLEM: dict[str, Any] = {
    "scene": SCENE,
    "movable": ["cup"],
    "costs": [
        {"type": "collision", "weight": 10.0, "margin": 0.01},
        {"type": "bounds"},
        {"type": "reach", "base": [0.0, -0.5], "radius": 0.8},
        {"type": "target", "object": "cup", "xy": [0.1, 0.2]},
    ],
    "solver": "langevin>osqp",
    "options": {"langevin": {"particles": 8, "steps": 5}, "osqp": {"max_iter": 5}},
    "seed": 0,
}
PROBLEM_KEYS = [*PROBLEM, "type", "weight", "object", "xy", "theta", "particles", "max_iter", "margin"]


def _load(text: str) -> None:
    try:
        load_problem("fuzz.yaml", text=text)
    except LIBRARY_ERRORS as e:
        _check_message(e)


@FUZZ_PROBLEMS
@given(mutated(PROBLEM, PROBLEM_KEYS))
def test_problem_documents(doc):
    try:
        text = yaml.safe_dump(doc, allow_unicode=True)
    except yaml.YAMLError:  # a value YAML cannot represent is not a file anyone can write
        return
    _load(text)


@FUZZ_PROBLEMS
@given(st.data())
def test_problem_text_mutated(data):
    """The YAML text of a valid problem with characters cut, inserted or replaced (anchors, tags, tabs,
    brackets among them)."""
    text = yaml.safe_dump(PROBLEM)
    pieces = st.sampled_from(
        [
            "&a ",
            "*a",
            "!!python/object:os.system ",
            "\t",
            "[",
            "]",
            "{",
            ": ",
            "- ",
            "\n",
            ".nan",
            "1e400",
            "~",
        ]
    )
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(text)))
        j = data.draw(st.integers(i, min(len(text), i + 6)))
        text = text[:i] + data.draw(st.one_of(pieces, st.text(max_size=4))) + text[j:]
    _load(text)
