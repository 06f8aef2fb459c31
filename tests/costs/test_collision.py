"""The hinge collision's fast path (pairs screened by bounding circles, the split-coordinate kernel)
against the full computation: the same values and gradients, bit for bit."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import torch

from scenescore.costs import Bounds, CostFn, HingeCollision, collision
from scenescore.costs.terms import CostError
from scenescore.problem.problem import Problem
from scenescore.scene.scene import Scene, SceneObject
from scenescore.solvers import get

pytestmark = pytest.mark.float_order


@pytest.fixture(autouse=True)
def _screen_small_batches(monkeypatch):
    """The screening on every batch, however small (by default small ones are computed in full)."""
    monkeypatch.setattr(collision, "SCREEN_ROWS", 0)


def _boxes(n: int, seed: int, fixed: int = 2) -> Scene:
    rng = np.random.default_rng(seed)
    objs = [
        SceneObject(
            f"o{i}", "box", (rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.4)), (0, 0, 0), fixed=i < fixed
        )
        for i in range(n)
    ]
    return Scene(objs, ((-1, -1), (1, 1)))


def _poses(scene: Scene, b: int, seed: int, spread: float = 0.8) -> torch.Tensor:
    """Random rotated poses; some rows squeezed together (overlaps), one set of boxes exactly touching
    edge to edge, and one row with everything far apart."""
    g = torch.Generator().manual_seed(seed)
    n = len(scene)
    x = torch.cat(
        [
            (torch.rand(b, n, 2, generator=g, dtype=torch.float64) * 2 - 1) * spread,
            (torch.rand(b, n, 1, generator=g, dtype=torch.float64) * 2 - 1) * math.pi,
        ],
        -1,
    )
    x[: b // 4, :, :2] *= 0.2  # crowded: most pairs overlap
    # row 0: axis-aligned boxes side by side, each touching the next (sd exactly 0 between neighbours)
    edge = 0.0
    for i, o in enumerate(scene.objects):
        half = o.size[0] / 2
        x[0, i] = torch.tensor([edge + half, 0.0, 0.0], dtype=torch.float64)
        edge += 2 * half
    x[1, :, :2] = torch.arange(n, dtype=torch.float64)[:, None] * 3.0  # all far apart
    return x


def _full(term: HingeCollision) -> HingeCollision:
    """The same term computed on every pair."""
    ref = copy.copy(term)
    ref._path = "full"
    return ref


def _value_grad_violation(term: HingeCollision, x: torch.Tensor) -> tuple[torch.Tensor, ...]:
    xr = x.clone().requires_grad_(True)
    v = term(xr)
    (g,) = torch.autograd.grad((v * torch.linspace(0.5, 2.0, len(v), dtype=v.dtype)).sum(), xr)
    with torch.no_grad():
        return v.detach(), g, term(x), term.violation(x)


@pytest.mark.parametrize("margin,power", [(0.0, 1), (0.02, 1), (0.0, 2), (0.03, 2)])
def test_fast_path_equals_the_full_computation_bit_for_bit(margin, power):
    scene = _boxes(9, seed=int(margin * 100) + power)
    term = HingeCollision(margin=margin, power=power).bind(scene)
    x = _poses(scene, 400, seed=power)
    near = term._near(x)
    assert 0.05 < float(near.float().mean()) < 0.9  # both screened and computed pairs
    g = _full(term).constraints(x)
    assert bool((g[~near] > 0).all())  # every skipped pair is apart by more than the margin
    assert bool((g < 0).any()) and bool(((g[0] + margin).abs() < 1e-9).any())  # overlapping, touching
    fast, full = _value_grad_violation(term, x), _value_grad_violation(_full(term), x)
    for a, b in zip(fast, full):
        assert torch.equal(a, b)
    assert float(fast[0][1]) == 0.0 and bool((fast[1][1] == 0).all())  # the far-apart row


def test_fast_path_in_float32_and_on_polygons_disks_and_ellipses():
    objs = [
        SceneObject("box", "box", (0.3, 0.1), (0, 0, 0), fixed=True),
        SceneObject("disk", "disk", (0.2, 0.2), (0, 0, 0), shape="disk"),
        SceneObject("ellipse", "disk", (0.25, 0.1), (0, 0, 0), shape="disk"),
        SceneObject("tri", "tri", (0.2, 0.2), (0, 0, 0), shape={"polygon": [[0, 0], [0.2, 0], [0, 0.15]]}),
        SceneObject("pt", "disk", (0.05, 0.05), (0, 0, 0), shape="disk"),
    ]
    term = HingeCollision(margin=0.01, power=2).bind(Scene(objs, ((-1, -1), (1, 1))))
    x = _poses(term.binding.scene, 60, seed=3, spread=0.5)
    for dtype in (torch.float64, torch.float32):
        fast, full = _value_grad_violation(term, x.to(dtype)), _value_grad_violation(_full(term), x.to(dtype))
        assert float(fast[0].max()) > 0
        for a, b in zip(fast, full):
            assert torch.equal(a, b)


def test_rows_and_jacobian_stay_exact_for_every_pair():
    scene = _boxes(6, seed=4)
    term = HingeCollision(margin=0.01).bind(scene)
    x = _poses(scene, 50, seed=5)
    ref = _full(term)  # every pair: the same operations, so the same bits
    assert torch.equal(term.constraints(x), ref.constraints(x))  # far pairs included: their true rows
    (g, j), (gr, jr) = term.jacobian(x), ref.jacobian(x)
    assert torch.equal(g, gr) and torch.equal(j, jr)
    fast, plain = _value_grad_violation(term, x), _value_grad_violation(ref, x)
    for a, b in zip(fast, plain):
        assert torch.equal(a, b)


def test_gradcheck_on_overlapping_and_separated_pairs():
    scene = _boxes(4, seed=6, fixed=1)
    term = HingeCollision(margin=0.01, power=2).bind(scene)
    x = _poses(scene, 6, seed=7, spread=0.4)[2:4].clone().requires_grad_(True)
    assert float(term(x).detach().min()) >= 0 and float(term(x).detach().max()) > 0
    assert torch.autograd.gradcheck(term, (x,), eps=1e-6, atol=1e-6)


def test_no_pairs():
    scene = _boxes(3, seed=8, fixed=3)  # nothing moves: no pair
    term = HingeCollision().bind(scene)
    x = _poses(scene, 4, seed=9)
    assert torch.equal(term(x), torch.zeros(4, dtype=torch.float64)) and term.violation(x).shape == (4,)
    assert term.constraints_below(x, torch.zeros(4, 0, dtype=torch.float64)).shape == (4, 0)


def test_nan_poses_still_reach_the_cost():
    scene = _boxes(4, seed=8)
    term = HingeCollision().bind(scene)
    x = _poses(scene, 3, seed=9)
    x[1, 3, 0] = float("nan")
    assert bool(torch.isnan(term(x)[1])) and not bool(torch.isnan(term(x)[2]))
    with pytest.raises(CostError, match="not finite"):
        (1.0 * term).bind(scene)(x)


def _pulled_together(seed: int) -> tuple[Problem, torch.Tensor]:
    """Six boxes pulled to the middle of a room with two fixed ones, and 40 starts (a quarter crowded)."""
    scene = _boxes(8, seed=seed)
    cost = (
        CostFn(lambda p: (p[..., :2] ** 2).sum((-1, -2)), name="pull")
        + 10.0 * HingeCollision(margin=0.01)
        + 10.0 * Bounds()
    )
    problem = Problem(scene, cost)
    x0 = _poses(scene, 40, seed=seed)
    x0[:, :2] = torch.tensor([[0.5, 0.5, 0.3], [-0.5, 0.2, 1.0]], dtype=torch.float64)  # the fixed boxes
    return problem, problem.full(x0)


@pytest.mark.parametrize("solver", ["langevin", "alm"])
def test_solvers_take_the_same_steps_on_the_fast_path(solver, monkeypatch):
    """The sampler's gradients and the refinement's rows (far pairs bounded, not computed) give the very
    same iterates as with every pair computed."""
    problem, x0 = _pulled_together(seed=10)
    options = {"particles": 40, "steps": 15} if solver == "langevin" else {"iterations": 8}
    fast = get(solver, **options).solve(problem, init=x0, seed=1)
    monkeypatch.setattr(problem.cost["collision"], "_path", "full")
    full = get(solver, **options).solve(problem, init=x0, seed=1)
    assert fast.samples is not None and full.samples is not None
    assert np.array_equal(fast.samples, full.samples)
    assert not np.array_equal(fast.samples, x0.numpy())


def test_rows_below_a_floor_are_exact_and_the_rest_above_it():
    scene = _boxes(7, seed=11)
    term = HingeCollision(margin=0.01).bind(scene)
    x = _poses(scene, 80, seed=12)
    exact = term.constraints(x)
    for level in (0.0, 0.05, 0.3):
        floor = torch.full_like(exact, level)
        floor[::2] += 0.1  # a floor per row
        rows = term.constraints_below(x, floor)
        below = exact <= floor
        assert torch.equal(rows[below], exact[below])
        assert bool((rows[~below] > floor[~below]).all()) and bool((rows <= exact).all())
        assert 0 < int((rows != exact).sum()) < rows.numel()  # some rows bounded, not computed


@pytest.mark.parametrize("margin", [0.0, 0.05])
def test_exact_check_skips_only_pairs_that_cannot_touch(margin):
    """``check`` builds shapely geometry only for pairs whose bounding circles come within the margin;
    its violations are those of every pair checked with shapely."""
    from scenescore.geometry.exact import collides, shapely_core

    scene = _boxes(7, 3)
    prob = Problem(scene, HingeCollision(margin=margin))
    term = next(iter(prob.cost))[1]
    objs = scene.objects
    found = 0
    for p in _poses(scene, 24, 5).numpy():
        got = {v.label for v in term.check(p, 1e-4)}
        want = set()
        for i, j in term.support():
            (ca, ra), (cb, rb) = shapely_core(objs[i], p[i]), shapely_core(objs[j], p[j])
            overlap = collides(objs[i], p[i], objs[j], p[j], 1e-4)
            if overlap or (margin > 1e-4 and ca.distance(cb) - ra - rb < margin - 1e-4):
                want.add(f"{objs[i].name} / {objs[j].name}")
        assert got == want
        found += len(want)
    assert found > 0


def test_bounds_check_matches_shapely_extents():
    """The bounds' exact check reads the placed core's vertices; the extents equal shapely's bounds."""
    from scenescore.geometry.exact import placed_core, shapely_core

    scene = _boxes(5, 4, fixed=0)
    for p in _poses(scene, 8, 6).numpy():
        for o, q in zip(scene.objects, p):
            pts, _ = placed_core(o, q)
            geo, _ = shapely_core(o, q)
            assert tuple(pts.min(0)) + tuple(pts.max(0)) == geo.bounds
    prob = Problem(scene, Bounds())
    far = _poses(scene, 2, 7).numpy()[1]  # all far apart: most outside the bounds
    names = {v.label for v in prob.check(far).violations}
    assert names and names <= set(scene.names)
