"""Hostile YAML problem files: every case raises :class:`ProblemError` naming the file, the line and the
key path (the nearest valid name for a misspelt one), or loads the problem it describes."""

from __future__ import annotations

import shutil

import pytest

from scenescore.problem.files import load_problem
from scenescore.problem.problem import ProblemError

from .helpers import SCENE, expect, write

BASE = "scene: scene.json\nmodel: m.ckpt\ncosts:\n  - {type: energy}\n  - {type: collision}\n"


@pytest.fixture
def folder(tmp_path, model_path, scene_path):
    shutil.copy(model_path, tmp_path / "m.ckpt")
    shutil.copy(scene_path, tmp_path / "scene.json")
    return tmp_path


def deep_yaml(n: int) -> str:
    return "scene: scene.json\ncosts: " + "[" * n + "]" * n + "\n"


LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi")
)

# -- files, encodings and YAML itself --------------------------------------------------------------------
FILES = [
    ("latin-1 bytes", BASE.encode() + "# caf\xe9\n".encode("latin-1"), (":6:", "not UTF-8")),
    ("empty", "", ("expected a mapping",)),
    ("a list", "- scene: scene.json\n", ("expected a mapping",)),
    ("a scalar", "hello\n", ("expected a mapping",)),
    ("tab indentation", "scene: scene.json\ncosts:\n\t- {type: bounds}\n", (":3:", "not valid YAML")),
    ("unclosed flow", "scene: scene.json\ncosts: [{type: bounds}\n", ("not valid YAML",)),
    (
        "python tag refused",
        "scene: !!python/object/apply:os.system ['true']\ncosts: [{type: bounds}]\n",
        ("not valid YAML",),
    ),
    ("billion laughs", LAUGHS, ("expands to more than",)),
    ("nested 200 deep", deep_yaml(200), ("nested deeper",)),
    ("nested 5000 deep", deep_yaml(5000), ("nested deeper",)),
    ("control character", BASE + "seed: 1\x08\n", (":6:", "not valid YAML", "#x0008")),
    ("NUL byte", "scene: scene.json\x00\ncosts: []\n", (":1:", "not valid YAML")),
    ("BOM then a valid problem", b"\xef\xbb\xbf" + BASE.encode() + b"seed: [1]\n", (":6:", "seed")),
    ("duplicate top key", BASE + "seed: 1\nseed: 2\n", (":7:", "duplicate key 'seed'")),
    (
        "duplicate cost key",
        "scene: scene.json\ncosts:\n  - {type: bounds, type: reach}\n",
        (":3:", "duplicate key 'type'"),
    ),
]


@pytest.mark.parametrize("label,text,names", FILES, ids=[f[0] for f in FILES])
def test_problem_file(folder, label, text, names):
    p = write(folder / "p.yaml", text)
    expect(lambda: load_problem(p), ProblemError, str(p), *names)


def test_problem_path_is_a_folder(folder):
    expect(lambda: load_problem(folder), ProblemError, str(folder), "folder")


def test_problem_path_missing(folder):
    expect(lambda: load_problem(folder / "nope.yaml"), ProblemError, "nope.yaml", "no such")


def test_problem_scene_is_a_folder(folder):
    (folder / "sub").mkdir()
    p = write(folder / "p.yaml", "scene: sub\ncosts: [{type: bounds}]\n")
    expect(lambda: load_problem(p), ValueError, "sub", "folder")


# -- keys and values of the schema -----------------------------------------------------------------------
SCHEMA = [
    ("misspelt top key", BASE + "solvr: langevin\n", (":6:", "unknown key 'solvr'", "did you mean 'solver'")),
    ("missing costs", "scene: scene.json\n", ("missing key 'costs'",)),
    ("empty costs", "scene: scene.json\ncosts: []\n", ("costs",)),
    ("costs a mapping", "scene: scene.json\ncosts: {type: bounds}\n", ("costs",)),
    (
        "cost type unknown",
        "scene: scene.json\ncosts: [{type: colision}]\n",
        ("costs[0]", "did you mean 'collision'"),
    ),
    ("cost type missing", "scene: scene.json\ncosts: [{weight: 1}]\n", ("costs[0]", "type")),
    (
        "cost key misspelt",
        "scene: scene.json\ncosts: [{type: collision, margn: 0.1}]\n",
        ("costs[0].margn", "did you mean 'margin'"),
    ),
    (
        "weight .inf",
        "scene: scene.json\ncosts: [{type: bounds, weight: .inf}]\n",
        (":2:", "costs[0].weight", "finite"),
    ),
    ("weight .nan", "scene: scene.json\ncosts: [{type: bounds, weight: .nan}]\n", ("costs[0].weight",)),
    ("weight negative", "scene: scene.json\ncosts: [{type: bounds, weight: -1}]\n", ("costs[0].weight",)),
    ("weight a word", "scene: scene.json\ncosts: [{type: bounds, weight: heavy}]\n", ("costs[0].weight",)),
    (
        "margin negative",
        "scene: scene.json\ncosts: [{type: collision, margin: -0.1}]\n",
        ("costs[0].margin",),
    ),
    (
        "target NaN",
        "scene: scene.json\ncosts: [{type: target, object: cup, xy: [.nan, 0]}]\n",
        ("costs[0].xy",),
    ),
    (
        "target inf",
        "scene: scene.json\ncosts: [{type: target, object: cup, xy: [0, -.inf]}]\n",
        ("costs[0].xy",),
    ),
    (
        "target 1e300",
        "scene: scene.json\ncosts: [{type: target, object: cup, xy: [1e300, 0]}]\n",
        ("costs[0].xy",),
    ),
    (
        "target theta NaN",
        "scene: scene.json\ncosts: [{type: target, object: cup, xy: [0, 0], theta: .nan}]\n",
        ("costs[0].theta",),
    ),
    (
        "target object misspelt",
        "scene: scene.json\ncosts: [{type: target, object: cupp, xy: [0, 0]}]\n",
        ("no object named 'cupp'", "did you mean 'cup'"),
    ),
    (
        "reach radius 0",
        "scene: scene.json\ncosts: [{type: reach, base: [0, 0], radius: 0}]\n",
        ("costs[0].radius",),
    ),
    (
        "reach base 3 numbers",
        "scene: scene.json\ncosts: [{type: reach, base: [0, 0, 0], radius: 1}]\n",
        ("costs[0].base",),
    ),
    ("collision power 3", "scene: scene.json\ncosts: [{type: collision, power: 3}]\n", ("costs[0].power",)),
    ("energy without model", "scene: scene.json\ncosts: [{type: energy}]\n", ("needs a 'model'",)),
    (
        "model missing file",
        "scene: scene.json\nmodel: gone.ckpt\ncosts: [{type: energy}]\n",
        ("model", "gone.ckpt"),
    ),
    ("scene missing file", "scene: gone.json\ncosts: [{type: bounds}]\n", ("scene", "gone.json")),
    (
        "scene inline bad",
        "scene: {objects: [{name: a}]}\ncosts: [{type: bounds}]\n",
        ("scene", "'a'", "missing field"),
    ),
    ("scene a number", "scene: 3\ncosts: [{type: bounds}]\n", ("scene",)),
    ("movable unknown object", BASE + "movable: [kup]\n", (":6:", "movable", "'kup'", "did you mean 'cup'")),
    ("movable a string", BASE + "movable: cup\n", ("movable",)),
    ("seed a word", BASE + "seed: lucky\n", (":6:", "seed")),
    ("seed 1e30", BASE + "seed: 1000000000000000000000000000000\n", (":6:", "seed")),
    ("seed a float", BASE + "seed: 1.5\n", (":6:", "seed")),
    ("solver unknown", BASE + "solver: langevin>osgp\n", ("solver", "did you mean 'osqp'")),
    ("solver empty stage", BASE + "solver: langevin>>osqp\n", ("solver",)),
    ("solver empty", BASE + "solver: ''\n", ("solver",)),
    ("options a list", BASE + "options: [langevin]\n", ("options",)),
    (
        "options for unknown solver",
        BASE + "options: {langevn: {particles: 8}}\n",
        ("options.langevn", "did you mean 'langevin'"),
    ),
    (
        "options for a solver not in the chain",
        BASE + "solver: langevin\noptions: {osqp: {max_iter: 5}}\n",
        (":7:", "options.osqp", "not in the chain"),
    ),
    (
        "unknown option",
        BASE + "solver: langevin\noptions:\n  langevin:\n    partikles: 8\n",
        (":9:", "options.langevin.partikles", "did you mean 'particles'"),
    ),
    (
        "option of another solver",
        BASE + "options:\n  osqp: {steps: 5}\n",
        (":7:", "options.osqp.steps", "unknown option"),
    ),
    (
        "particles: eight",
        BASE + "options:\n  langevin:\n    particles: eight\n",
        (":8:", "options.langevin.particles", "integer", "'eight'"),
    ),
    (
        "particles 0",
        BASE + "options:\n  langevin: {particles: 0}\n",
        (":7:", "options.langevin.particles", ">= 1"),
    ),
    ("particles -8", BASE + "options:\n  langevin: {particles: -8}\n", ("options.langevin.particles",)),
    ("particles 8.5", BASE + "options:\n  langevin: {particles: 8.5}\n", ("options.langevin.particles",)),
    ("steps -1", BASE + "options:\n  langevin: {steps: -1}\n", ("options.langevin.steps",)),
    ("step_init 0", BASE + "options:\n  langevin: {step_init: 0}\n", ("options.langevin.step_init", "> 0")),
    (
        "step_init negative",
        BASE + "options:\n  langevin: {step_init: -0.1}\n",
        ("options.langevin.step_init",),
    ),
    ("step_final NaN", BASE + "options:\n  langevin: {step_final: .nan}\n", ("options.langevin.step_final",)),
    ("noise negative", BASE + "options:\n  langevin: {noise: -1}\n", ("options.langevin.noise",)),
    ("temperature 0", BASE + "options:\n  langevin: {temperature: 0}\n", ("options.langevin.temperature",)),
    (
        "projection unknown",
        BASE + "options:\n  langevin: {projection: exact}\n",
        ("options.langevin.projection",),
    ),
    (
        "threads, not an option",
        BASE + "options:\n  langevin: {threads: 2}\n",
        ("options.langevin.threads", "--threads"),
    ),
    (
        "candidates negative",
        BASE + "options:\n  langevin: {candidates: -1}\n",
        ("options.langevin.candidates",),
    ),
    ("max_iter -1", BASE + "options:\n  osqp: {max_iter: -1}\n", (":7:", "options.osqp.max_iter", ">= 0")),
    ("max_iter a string", BASE + "options:\n  osqp: {max_iter: many}\n", ("options.osqp.max_iter",)),
    ("trust_init negative", BASE + "options:\n  osqp: {trust_init: -0.05}\n", ("options.osqp.trust_init",)),
    ("tol_step NaN", BASE + "options:\n  osqp: {tol_step: .nan}\n", ("options.osqp.tol_step",)),
    (
        "casadi tol negative",
        BASE + "solver: langevin>casadi\noptions:\n  casadi: {tol: -1}\n",
        ("options.casadi.tol",),
    ),
    (
        "casadi max_iter -1",
        BASE + "solver: langevin>casadi\noptions:\n  casadi: {max_iter: -1}\n",
        ("options.casadi.max_iter",),
    ),
    (
        "casadi energy unknown",
        BASE + "solver: langevin>casadi\noptions:\n  casadi: {energy: torch}\n",
        ("options.casadi.energy",),
    ),
]


@pytest.mark.parametrize("label,text,names", SCHEMA, ids=[s[0] for s in SCHEMA])
def test_problem_schema(folder, label, text, names):
    p = write(folder / "p.yaml", text)
    expect(lambda: load_problem(p), ProblemError, str(p), *names)


VALID = [
    (
        "options for every stage",
        BASE + "solver: langevin>osqp\noptions: {langevin: {particles: 8, steps: 5}, osqp: {max_iter: 0}}\n",
    ),
    ("a negative seed", BASE + "seed: -3\n"),
    ("weight 0", BASE + "  - {type: bounds, weight: 0}\n"),
    (
        "inline scene",
        "scene: {objects: [{name: a, category: c, size: [0.1, 0.1], pose: null}]}\ncosts: [{type: bounds}]\n",
    ),
    (
        "unicode names",
        "scene: {objects: [{name: tasse, category: caf\u00e9, size: [0.1, 0.1], pose: null}]}\ncosts: [{type: bounds}]\n",
    ),
]


@pytest.mark.parametrize("label,text", VALID, ids=[v[0] for v in VALID])
def test_problem_valid_extremes(folder, label, text):
    lp = load_problem(write(folder / "p.yaml", text))
    assert lp.problem.movable


def test_inline_scene_with_an_object_larger_than_its_bounds(folder):
    text = "scene: {objects: [{name: rug, category: c, size: [3, 3], pose: null}]}\ncosts: [{type: bounds}]\n"
    p = write(folder / "p.yaml", text)
    expect(lambda: load_problem(p), ProblemError, str(p), "'rug'", "does not fit")


def test_problem_scene_file_errors_name_the_scene_file(folder):
    bad = dict(SCENE, objects=[dict(SCENE["objects"][0], size=[1e20, 1])])
    write(folder / "scene.json", bad)
    p = write(folder / "p.yaml", "scene: scene.json\ncosts: [{type: bounds}]\n")
    expect(lambda: load_problem(p), ValueError, "scene.json", "'plate'", "'size'")
