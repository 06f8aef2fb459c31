"""The selection: which objects to move, by a forward selection of sets with a backward check, each
candidate set re-placed by the learned energy (the others where they are), every set of every scene in
one batched chain per number of objects."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch

from ...models import ScoreModel
from ...problem.problem import Problem
from ...runtime.devices import generator
from ...scene.scene import Scene
from ...solvers.kernel import screen
from ...solvers.langevin import LangevinSolver
from ..placement import covering, placement_problem
from .draws import exchanges, near_draws, pair_rows, swap_draws
from .problem import whole_cost
from .types import TidyOptions

__all__ = ["PAIR_CANDIDATES", "SWAP_CANDIDATES", "select_moves", "best_replacements"]

#: the selection tries pairs of objects among this many best single moves when no single move pays
PAIR_CANDIDATES = 5
#: each step of the selection also tries this many pairs whose exchange (each object at the other's
#: position) lowers the whole cost the most
SWAP_CANDIDATES = 3


def select_moves(
    model: ScoreModel,
    scenes: list[Scene],
    problems: list[Problem],
    o: TidyOptions,
    seed: int,
    on_change: Callable[[int, np.ndarray], None] | None = None,
) -> list[np.ndarray]:
    """Which objects to move, per scene, by forward selection with a backward check: each step re-places
    the chosen set with one more movable object (the others where they are) and keeps the set whose
    best placement lowers the whole cost (energy, effort, overlap, bounds, reach) the most; then each
    chosen object is tried back where it is, the rest re-placed, and dropped when that lowers the cost
    (a first pick that only made room for the right one). When no such step lowers the cost, pairs of
    the :data:`PAIR_CANDIDATES` best single additions are tried together (two objects that are each
    where the other belongs: neither move pays alone); it stops when that fails too. Each step also
    tries the chosen set with the :data:`SWAP_CANDIDATES` pairs whose exchange lowers the cost most
    (:func:`_swap_sets`), so that two objects in each other's places are found even where a false single
    move pays first. ``on_change(k, poses)`` is called whenever scene ``k``'s poses change.
    Returns each scene's poses ``(N, 3)``."""
    states = [s.poses() for s in scenes]
    chosen: list[list[str]] = [[] for _ in scenes]
    best = [float(whole_cost(p, x[None])[0]) for p, x in zip(problems, states)]
    limit = [len(p.movable) if o.max_moves is None else min(o.max_moves, len(p.movable)) for p in problems]
    active = [k for k in range(len(scenes)) if limit[k] > 0]
    step = 0
    while active and step < 4 * max(limit):
        step += 1
        grow = {
            k: [[*chosen[k], n] for n in problems[k].movable if n not in chosen[k]]
            + (
                _swap_sets(problems[k], states[k], best[k], chosen[k])
                if len(chosen[k]) + 2 <= limit[k]
                else []
            )
            for k in active
        }
        shrink = {
            k: [[m for m in chosen[k] if m != n] for n in chosen[k]] for k in active if len(chosen[k]) > 1
        }
        jobs = {k: (grow[k] if len(chosen[k]) < limit[k] else []) + shrink.get(k, []) for k in active}
        every: dict[int, list[tuple[float, list[str]]]] = {}
        found = best_replacements(model, scenes, problems, jobs, o, seed + 7919 * step, states, every)
        still, stuck = [], []
        for k in active:
            if k in found and found[k][0] < best[k] - o.gain_tol:
                best[k], states[k], chosen[k] = found[k]
                still.append(k)
            elif len(chosen[k]) + 2 <= limit[k]:
                stuck.append(k)
        if stuck:
            pairs = {k: _pair_sets(chosen[k], every.get(k, [])) for k in stuck}
            found = best_replacements(model, scenes, problems, pairs, o, seed + 7919 * step + 1, states)
            for k in stuck:
                if k in found and found[k][0] < best[k] - o.gain_tol:
                    best[k], states[k], chosen[k] = found[k]
                    still.append(k)
        active = sorted(still)
        if on_change is not None:
            for k in active:
                on_change(k, states[k])
    return states


def _swap_sets(problem: Problem, x: np.ndarray, best: float, chosen: list[str]) -> list[list[str]]:
    """The chosen set with each of the :data:`SWAP_CANDIDATES` pairs of movable objects not in it, of
    different kinds (:attr:`~scenescore.scene.scene.SceneObject.kind`: category or size), whose exchange at
    the poses ``x (N, 3)`` (each at the other's position, with its own heading or the other's, the
    better) lowers the whole cost below ``best`` the most; one batched cost evaluation."""
    scene = problem.scene
    free = [n for n in problem.movable if n not in chosen]
    pairs = [(a, b) for i, a in enumerate(free) for b in free[i + 1 :] if scene[a].kind != scene[b].kind]
    if not pairs or SWAP_CANDIDATES <= 0:
        return []
    xs = exchanges(x, [(scene.index(a), scene.index(b)) for a, b in pairs])  # (2P, N, 3)
    costs = whole_cost(problem, xs).reshape(2, len(pairs)).min(0)  # (P,): the better of the two exchanges
    order = [j for j in np.argsort(costs, kind="stable") if costs[j] < best][:SWAP_CANDIDATES]
    return [[*chosen, *pairs[j]] for j in order]


def _pair_sets(chosen: list[str], tried: list[tuple[float, list[str]]]) -> list[list[str]]:
    """The chosen set with two more objects, every pair among the :data:`PAIR_CANDIDATES` single additions
    to it that cost least (``tried``: each tried set's lowest cost)."""
    singles = sorted((c, names[-1]) for c, names in tried if len(names) == len(chosen) + 1)
    top = [n for _, n in singles[:PAIR_CANDIDATES]]
    return [[*chosen, a, b] for i, a in enumerate(top) for b in top[i + 1 :]]


def best_replacements(
    model: ScoreModel,
    scenes: list[Scene],
    problems: list[Problem],
    jobs: dict[int, list[list[str]]],
    o: TidyOptions,
    seed: int,
    warm: list[np.ndarray] | None = None,
    every: dict[int, list[tuple[float, list[str]]]] | None = None,
) -> dict[int, tuple[float, np.ndarray, list[str]]]:
    """Per scene ``k`` of ``jobs``: the lowest cost of ``problems[k]`` found by re-placing one of its
    sets of objects (the others where they are; every set of every scene placed in one batched chain
    per size), its poses ``(N, 3)`` and that set. ``warm``: each scene's poses so far; half the draws
    keep the objects of the set that those poses moved where they put them. ``every``, when given, is
    filled with each scene's ``(lowest cost, set)`` of every set."""

    flat = [(k, names) for k, sets in jobs.items() for names in sets if names]
    blanks, starts = [], []
    gen = generator(seed, model.device)
    keep = o.propose.particles
    for k, names in flat:
        blank = scenes[k].copy()
        for m in names:
            blank.objects[blank.index(m)].pose = None
        # the fused network alone; the whole cost judges overlap below
        p = placement_problem(model, blank, energy_only=True)
        # as many draws as placement screens for these bounds (small objects in large bounds need more);
        # a share of them proposed beside the objects that stay, as the data has them, the rest uniform
        draws = max(covering(o.propose, model, [scenes[k]]).candidates, keep)
        x = p.initial(draws, gen, proposals=o.propose.proposals)  # (draws, N, 3): the others where they are
        rows = [scenes[k].index(m) for m in names]
        if warm is not None:
            now = scenes[k].poses()
            moved = [i for i in rows if not np.array_equal(warm[k][i], now[i])]
            if moved:
                x[: draws // 2, moved] = torch.as_tensor(warm[k][moved], dtype=x.dtype, device=x.device)
        near_draws(x, scenes[k], rows, model.config.length_scale, gen)
        swap_draws(x, scenes[k], names)
        blanks.append(p)
        starts.append(screen(p.cost, x, keep))
    found: dict[int, tuple[float, np.ndarray, list[str]]] = {}
    solver = LangevinSolver(o.propose)
    for idx in _by_object_count(blanks):
        results = solver.solve_many([blanks[j] for j in idx], seed=seed, init=[starts[j] for j in idx])
        for j, res in zip(idx, results):
            k, names = flat[j]
            assert res.samples is not None
            # the chain's samples and the set's exact exchanges (a chain may leave a swap it was started on)
            pairs = pair_rows(scenes[k], names)
            got = np.asarray(res.samples, dtype=float)
            if pairs:
                got = np.concatenate([got, exchanges(scenes[k].poses(), pairs)])
            costs = whole_cost(problems[k], got)
            i = int(np.argmin(costs))
            if every is not None:
                every.setdefault(k, []).append((float(costs[i]), list(names)))
            if k not in found or costs[i] < found[k][0]:
                found[k] = (float(costs[i]), got[i], list(names))
    return found


def _by_object_count(problems: Sequence[Problem]) -> list[list[int]]:
    """Indices of ``problems`` grouped by their number of objects (one batched chain each)."""
    groups: dict[int, list[int]] = {}
    for j, p in enumerate(problems):
        groups.setdefault(p.n, []).append(j)
    return list(groups.values())
