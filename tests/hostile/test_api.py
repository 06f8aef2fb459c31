"""Hostile values through the Python API: option dataclasses, solvers, problems, training, placement and
the heatmap. Each case raises the library's ``ValueError`` subclass naming the setting or object, or
returns the right result for a valid extreme."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from scenescore.costs import CostError
from scenescore.errors import ConfigError
from scenescore.problem.problem import Problem, ProblemError
from scenescore.scene.scene import Scene, SceneError

from .helpers import SCENE, expect, with_object

OPTIONS = [
    # (label, factory, error class, names)
    ("LangevinConfig steps -1", lambda: _lc(steps=-1), ConfigError, ("steps", "-1")),
    ("LangevinConfig steps 2.5", lambda: _lc(steps=2.5), ConfigError, ("steps",)),
    ("LangevinConfig steps True", lambda: _lc(steps=True), ConfigError, ("steps",)),
    ("LangevinConfig step_init 0", lambda: _lc(step_init=0), ConfigError, ("step_init", "> 0")),
    ("LangevinConfig step_final -1e-3", lambda: _lc(step_final=-1e-3), ConfigError, ("step_final",)),
    ("LangevinConfig noise -1", lambda: _lc(noise=-1.0), ConfigError, ("noise",)),
    ("LangevinConfig noise NaN", lambda: _lc(noise=math.nan), ConfigError, ("noise",)),
    ("LangevinConfig max_delta inf", lambda: _lc(max_delta=math.inf), ConfigError, ("max_delta",)),
    ("LangevinConfig temperature 0", lambda: _lc(temperature=0.0), ConfigError, ("temperature",)),
    ("LangevinConfig resample -1", lambda: _lc(resample=-1), ConfigError, ("resample",)),
    ("LangevinConfig steps 1e9", lambda: _lc(steps=10**9), ConfigError, ("steps",)),
    ("TrainConfig iterations -5", lambda: _tc(iterations=-5), ConfigError, ("iterations", "-5")),
    ("TrainConfig iterations '600'", lambda: _tc(iterations="600"), ConfigError, ("iterations",)),
    ("TrainConfig negatives 0", lambda: _tc(negatives=0), ConfigError, ("negatives",)),
    ("TrainConfig lr 0", lambda: _tc(lr=0.0), ConfigError, ("lr",)),
    ("TrainConfig lr NaN", lambda: _tc(lr=math.nan), ConfigError, ("lr",)),
    ("TrainConfig unknown field", lambda: _tc(iters=5), TypeError, ("iters",)),
    ("EnergyConfig hidden 0", lambda: _ec(hidden=0), ConfigError, ("hidden",)),
    ("EnergyConfig layers -1", lambda: _ec(layers=-1), ConfigError, ("layers",)),
    ("EnergyConfig activation", lambda: _ec(activation="relu6"), ConfigError, ("activation",)),
    ("LangevinOptions particles 0", lambda: _lo(particles=0), ConfigError, ("particles",)),
    (
        "LangevinOptions particles 'eight'",
        lambda: _lo(particles="eight"),
        ConfigError,
        ("particles", "'eight'"),
    ),
    ("LangevinOptions particles 1e9", lambda: _lo(particles=10**9), ConfigError, ("particles",)),
    ("LangevinOptions projection", lambda: _lo(projection="exact"), ConfigError, ("projection",)),
    ("SQPOptions max_iter -1", lambda: _so(max_iter=-1), ConfigError, ("osqp", "max_iter")),
    ("SQPOptions trust_init -1", lambda: _so(trust_init=-1.0), ConfigError, ("trust_init",)),
    (
        "SQPOptions trust_init > trust_max",
        lambda: _so(trust_init=1.0),
        ConfigError,
        ("trust_init", "trust_max"),
    ),
    ("SQPOptions slack NaN", lambda: _so(slack=math.nan), ConfigError, ("slack",)),
    ("SQPOptions max_iter '50'", lambda: _so(max_iter="50"), ConfigError, ("max_iter",)),
    ("CasadiOptions tol 0", lambda: _co(tol=0.0), ConfigError, ("casadi", "tol")),
    ("CasadiOptions max_iter -1", lambda: _co(max_iter=-1), ConfigError, ("max_iter",)),
    ("CasadiOptions energy", lambda: _co(energy="jit"), ConfigError, ("energy",)),
    ("get unknown solver", lambda: _get("lbfgs"), ProblemError, ("'lbfgs'",)),
    ("get near-miss solver", lambda: _get("langevn"), ProblemError, ("did you mean 'langevin'",)),
    (
        "get unknown langevin option",
        lambda: _get("langevin", partikles=8),
        ProblemError,
        ("'partikles'", "did you mean 'particles'"),
    ),
    (
        "get unknown osqp option",
        lambda: _get("osqp", maxiter=8),
        ProblemError,
        ("'maxiter'", "did you mean 'max_iter'"),
    ),
    ("get osqp option of langevin", lambda: _get("osqp", particles=8), ProblemError, ("osqp", "'particles'")),
    ("get empty chain stage", lambda: _get("langevin>"), ProblemError, ("''",)),
    ("heatmap resolution NaN", lambda: _grid(math.nan), ConfigError, ("resolution",)),
    ("heatmap resolution -1", lambda: _grid(-1.0), ConfigError, ("resolution",)),
    ("make_encoder unknown", lambda: _enc("resnet"), SceneError, ("'resnet'",)),
    ("scenario unknown", lambda: _scenario("dinner"), SceneError, ("'dinner'",)),
    ("image encoder ppm 0", lambda: _enc("image", {"ppm": 0}), ValueError, ("ppm",)),
]


def _lc(**kw):
    from scenescore.solvers.kernel import LangevinConfig

    return LangevinConfig(**kw)


def _tc(**kw):
    from scenescore.learn import TrainConfig

    return TrainConfig(**kw)


def _ec(**kw):
    from scenescore.models import EnergyConfig

    return EnergyConfig(**{"feat_dim": 4, **kw})


def _lo(**kw):
    from scenescore.solvers.langevin import LangevinOptions

    return LangevinOptions(**kw)


def _so(**kw):
    from scenescore.solvers.sqp import SQPOptions

    return SQPOptions(**kw)


def _co(**kw):
    from scenescore.solvers.casadi import CasadiOptions

    return CasadiOptions(**kw)


def _get(name, **kw):
    from scenescore.solvers import get

    return get(name, **kw)


def _grid(resolution):
    from scenescore.encoders import make_encoder
    from scenescore.models import ScoreModel
    from scenescore.planning.heatmap import energy_grid

    m = ScoreModel.create(make_encoder("footprint"), hidden=4, embed_dim=4)
    return energy_grid(m, Scene.from_dict(SCENE), "cup", resolution)


def _enc(name, config=None):
    from scenescore.encoders import make_encoder

    return make_encoder(name, config)


def _scenario(name):
    from scenescore.scenarios import get

    return get(name)


@pytest.mark.parametrize("label,fn,error,names", OPTIONS, ids=[o[0] for o in OPTIONS])
def test_option(label, fn, error, names):
    expect(fn, error, *names)


# -- problems and solving ----------------------------------------------------------------------------------
def _bounds_problem(d=None, **kw):
    from scenescore.costs import Bounds

    return Problem(Scene.from_dict(d or SCENE), Bounds(), **kw)


PROBLEMS = [
    (
        "not a scene",
        lambda: Problem({"objects": []}, _bounds()),
        ProblemError,
        ("expected a scenescore Scene",),
    ),
    ("movable unknown", lambda: _bounds_problem(movable=["spoon"]), ProblemError, ("'spoon'",)),
    (
        "movable fixed",
        lambda: _bounds_problem(_fixed_fork(), movable=["fork"]),
        ProblemError,
        ("'fork'", "fixed"),
    ),
    (
        "movable too large",
        lambda: _bounds_problem(_big_fork(), movable=["fork"]),
        ProblemError,
        ("'fork'", "does not fit"),
    ),
    (
        "nothing may move",
        lambda: _bounds_problem(with_object(2, pose=[0.3, 0.3, 0.0]), movable=[]),
        ProblemError,
        ("no object may move",),
    ),
    ("init of the wrong shape", lambda: _solve(init=np.zeros((2, 3))), ProblemError, ("init", "shape")),
    ("init with NaN", lambda: _solve(init=np.full((3, 3), np.nan)), ProblemError, ("init", "NaN")),
    ("solve bogus solver", lambda: _solve(solver="bogus"), ProblemError, ("'bogus'",)),
    (
        "solve particles 0",
        lambda: _solve(options={"langevin": {"particles": 0}}),
        ProblemError,
        ("particles",),
    ),
    (
        "solve step_init -1",
        lambda: _solve(options={"langevin": {"step_init": -1.0}}),
        ProblemError,
        ("step_init",),
    ),
    (
        "solve max_iter -1",
        lambda: _solve(solver="langevin>osqp", options={"osqp": {"max_iter": -1}}),
        ProblemError,
        ("max_iter",),
    ),
    ("target NaN", lambda: _target((math.nan, 0.0)), CostError, ("PoseTarget", "xy")),
    ("target unknown object", lambda: _target((0.0, 0.0), "spoon"), ValueError, ("'spoon'",)),
    ("collision margin -1", lambda: _collision(margin=-1.0), CostError, ("margin",)),
    ("weight NaN", lambda: math.nan * _bounds(), CostError, ("weight",)),
    ("weight -1", lambda: -1.0 * _bounds(), CostError, ("weight",)),
]


def _bounds():
    from scenescore.costs import Bounds

    return Bounds()


def _fixed_fork():
    return with_object(1, fixed=True)


def _big_fork():
    d = with_object(1, size=[3.0, 3.0])
    d["objects"][1]["pose"] = [0.0, 0.0, 0.0]
    return d


def _solve(solver="langevin", init=None, options=None):
    from scenescore.solvers import solve

    opts = {"langevin": {"particles": 4, "steps": 2, "final_descent": 0}}
    for k, v in (options or {}).items():
        opts[k] = {**opts.get(k, {}), **v}
    return solve(_bounds_problem(), solver, init=init, options=opts)


def _target(xy, name="cup"):
    from scenescore.costs import PoseTarget

    return Problem(Scene.from_dict(SCENE), PoseTarget(name, xy))


def _collision(**kw):
    from scenescore.costs import HingeCollision

    return HingeCollision(**kw)


@pytest.mark.parametrize("label,fn,error,names", PROBLEMS, ids=[p[0] for p in PROBLEMS])
def test_problem_api(label, fn, error, names):
    expect(fn, error, *names)


# -- valid extremes: the right answer ------------------------------------------------------------------------
def test_solver_with_one_particle_and_no_steps():
    r = _solve(options={"langevin": {"particles": 1, "steps": 0}})
    assert np.isfinite(r.poses).all()


def test_osqp_with_max_iter_zero_returns_its_start():
    r = _solve(solver="langevin>osqp", options={"osqp": {"max_iter": 0}})
    assert np.isfinite(r.poses).all()


def test_a_tiny_object_is_placed_inside_the_bounds():
    d = with_object(2, size=[1e-3, 1e-3])
    r = __import__("scenescore.solvers", fromlist=["solve"]).solve(
        _bounds_problem(d), "langevin", options={"langevin": {"particles": 4, "steps": 3}}
    )
    x, y, _ = r.poses[2]
    assert -0.6 <= x <= 0.6 and -0.6 <= y <= 0.6


def test_an_object_that_fits_only_turned_is_placed_turned():
    from scenescore.solvers import solve

    d = with_object(2, size=[1.6, 0.05])  # longer than the 1.2 m table, shorter than its diagonal
    d["objects"] = [d["objects"][2]]
    r = solve(_bounds_problem(d), "langevin>osqp", options={"langevin": {"particles": 16, "steps": 20}})
    assert r.success, r.summary()
    assert abs(math.cos(r.poses[0][2])) < 0.9  # turned off the axes


def test_place_with_a_scene_without_unknowns_returns_a_copy(model_path):
    from scenescore.models import load
    from scenescore.planning.placement import place

    s = Scene.from_dict(with_object(2, pose=[0.3, 0.3, 0.0]))
    out = place(load(model_path), s)
    assert out == s and out is not s


def test_place_particles_zero_is_refused(model_path):
    from scenescore.models import load
    from scenescore.planning.placement import PLACE, place

    expect(
        lambda: place(load(model_path), Scene.from_dict(SCENE), replace(PLACE, particles=0)),
        ConfigError,
        "particles",
    )


def test_train_refuses_one_object_scenes():
    from scenescore.learn import TrainConfig, fit

    s = Scene.from_dict(dict(SCENE, objects=SCENE["objects"][:1]))
    expect(
        lambda: fit([s, s], TrainConfig(members=1, iterations=1), progress=False),
        SceneError,
        "no example scene",
    )


def test_with_poses_of_the_wrong_shape():
    expect(lambda: Scene.from_dict(SCENE).with_poses(np.zeros((2, 3))), SceneError, "with_poses", "(3, 3)")


def test_with_poses_nan_cannot_be_written(tmp_path):
    s = Scene.from_dict(SCENE).with_poses(np.full((3, 3), np.nan))
    expect(lambda: s.to_json(tmp_path / "s.json"), SceneError, "'plate'", "not finite")


def test_energy_of_a_scene_with_extreme_but_valid_coordinates(model_path):
    from scenescore.models import load

    m = load(model_path)
    d = with_object(2, pose=[9000.0, -9000.0, 999.0])
    d["bounds"] = [[-1e4, -1e4], [1e4, 1e4]]
    s = Scene.from_dict(d)
    e = m.energy_fn(s)(torch.as_tensor(s.poses()[None], dtype=m.dtype))
    assert torch.isfinite(e).all()
