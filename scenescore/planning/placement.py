"""Placing objects whose pose is unknown: a problem with the learned energy, solved by ``langevin``.

Placement has no sampler of its own: :func:`place` builds the :class:`~scenescore.problem.problem.Problem` of the
learned energy with the unknown objects movable and solves it with the ``langevin`` solver under the
placement defaults (:data:`PLACE`), on one torch thread, a large population's energy in pieces side by
side within the run's budget (``--threads``, :func:`~scenescore.thread_budget`). Several unknown objects start from :func:`in_turn`'s particles, found one object at a
time and then moved in pairs, and then move together in the chain.
"""

from __future__ import annotations

import math
import os
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from typing import Protocol, cast

import numpy as np
import torch
from torch import Tensor
from tqdm.auto import tqdm

from ..costs import Cost, HingeCollision, LearnedEnergy
from ..encoders import Encoder
from ..geometry.poses import compose_poses
from ..learn import ONE_NETWORK, Run, TrainConfig, fit
from ..learn.config import compiled_placements
from ..models import ScoreModel
from ..problem.problem import FEASIBILITY_TOL, Problem
from ..runtime.devices import draw, generator
from ..runtime.threads import torch_threads
from ..scene.scene import Scene, SceneError
from ..solvers import Result, solve
from ..solvers.kernel import PLACEMENT, screen
from ..solvers.langevin import LangevinOptions, LangevinSolver

__all__ = [
    "PLACE",
    "OVERLAP_WEIGHT",
    "place",
    "place_many",
    "in_turn",
    "refining",
    "placement_problem",
    "covering",
    "CANDIDATE_DENSITY",
    "non_overlap",
    "overlapping",
    "Placer",
    "SceneScorePlacer",
]


#: placement's default: 64 particles seeded by the best of 2048 draws (more in bounds large for the
#: objects: :func:`covering`), half uniform, half proposed by the learned energy (its data's poses beside
#: the scene's known objects), the PLACEMENT schedule; the answer is the best particle that puts no
#: object where the data has none of its category (at a bound none comes near, or far from the rest)
PLACE = LangevinOptions(particles=64, candidates=2048, proposals=0.5, chain=PLACEMENT, trusted_first=True)
#: uniform candidates per square length scale of the bounds that placement screens at the least, so that
#: small parts on a large board start near their slot (docs/studies.md, "Behind the defaults")
CANDIDATE_DENSITY = 2.0
MAX_COVERING = 32_768  # the most candidates that covering the bounds asks for
#: a pair move (:func:`_in_pairs`) draws an object beside one of this many known objects nearest to it
NEAR_ANCHORS = 8
#: the weight of non-overlap in placement: energy per length scale of penetration (free of units)
OVERLAP_WEIGHT = 10.0


def covering(options: LangevinOptions, model: ScoreModel, scenes: list[Scene]) -> LangevinOptions:
    """``options`` with at least :data:`CANDIDATE_DENSITY` candidates per square length scale of the
    largest bounds of ``scenes`` (at most :data:`MAX_COVERING`), so that small objects in large bounds
    start near their slot as often as large ones; free of units. Placement applies it to its defaults
    (options given by hand are used as given); ``candidates=0`` (no screening) stays."""
    if options.candidates == 0:
        return options
    area = max((s.bounds[1][0] - s.bounds[0][0]) * (s.bounds[1][1] - s.bounds[0][1]) for s in scenes)
    need = math.ceil(CANDIDATE_DENSITY * area / model.config.length_scale**2 / 1024) * 1024
    need = min(need, MAX_COVERING)
    return options if need <= options.candidates else replace(options, candidates=need)


def non_overlap(model: ScoreModel, scene: Scene, names: list[str] | None = None) -> HingeCollision | None:
    """Hinge non-overlap between each object of ``names`` (default: those to place) and every other
    object, except category pairs that overlap in the model's training data (a lamp on its nightstand);
    each pair names the object of ``names`` first. None when no pair is left."""
    trust = model.trust
    todo = set(scene.unknown if names is None else names)
    pairs = [
        [a.name, b.name] if a.name in todo else [b.name, a.name]
        for k, a in enumerate(scene.objects)
        for b in scene.objects[k + 1 :]
        if (a.name in todo or b.name in todo) and not (trust and trust.may_overlap(a.category, b.category))
    ]
    return HingeCollision(pairs=pairs, name="overlap") if pairs else None


def overlapping(model: ScoreModel, scene: Scene, names: list[str]) -> list[tuple[str, str]]:
    """Pairs ``(placed, other)`` that overlap in ``scene`` (every pose known): the exact check of
    :func:`non_overlap`'s term over ``names``, at the feasibility tolerance."""
    hinge = non_overlap(model, scene, names)
    if hinge is None:
        return []
    term = cast(HingeCollision, hinge.bind(scene, names))
    all_names = scene.names
    by_label = {lab: (all_names[i], all_names[j]) for lab, (i, j) in zip(term.labels(), term.support())}
    return [by_label[v.label] for v in term.check(scene.poses(), FEASIBILITY_TOL)]


def placement_problem(
    model: ScoreModel,
    scene: Scene,
    energy_only: bool = False,
    extra: Cost | None = None,
    relations: bool = True,
) -> Problem:
    """The problem :func:`place` solves, the unknown poses movable: the learned energy plus
    :func:`non_overlap` (``energy_only``: the learned energy alone, the paper's protocol), plus
    ``extra`` when given (such as :class:`~scenescore.costs.ExampleRelations` of the example scenes).
    ``relations``: whether a flagged placement's flags name the relation it doubts
    (:class:`~scenescore.costs.LearnedEnergy`'s option of that name)."""
    if not scene.unknown:
        raise SceneError("place: the scene has no object with an unknown pose (pose: null) to place")
    cost: Cost = LearnedEnergy(model, relations=relations)
    hinge = None if energy_only else non_overlap(model, scene)
    if hinge is not None:
        cost = cost + (OVERLAP_WEIGHT / model.config.length_scale) * hinge
    if extra is not None:
        cost = cost + extra
    return Problem(scene, cost, movable=scene.unknown, name="place")


def in_turn(
    model: ScoreModel, scene: Scene, options: LangevinOptions, seed: int = 0, energy_only: bool = False
) -> Tensor:
    """Starting particles for placing several unknown objects, found one object at a time and then moved
    in pairs; ``(particles, N, 3)`` float64 for :func:`placement_problem` of ``scene``.

    The stages are a beam over the objects in the scene's order: the first unknown object is screened
    alone (the later ones left out of the scene), its best ``particles`` draws kept; each next one is
    drawn beside every kept particle and screened with the ones before it in place. Screened jointly, a
    draw would have to put every object on a free slot at once; in turn, each stage screens one object's
    slot, so the search grows with the objects to place, not with the product of their slots. Each
    object is screened beside the next one to place (:func:`_partner`). The stages then leave the
    particles to :func:`_in_pairs`, which moves one or two objects at a time in the whole scene. Each
    stage and each object's moves draw half the candidates, so the two phases cost about what the
    stages alone cost with all the candidates."""
    names = scene.unknown
    keep = options.particles
    draws = max(options.candidates // 2, keep)
    gen = generator(seed, model.device)
    beam: Tensor | None = None  # (particles, k, 3): the first k unknown objects' poses in each particle
    for k in range(len(names)):
        ahead = k + 1 < len(names)
        later = set(names[k + 2 :] if ahead else names[k + 1 :])
        sub = replace(scene, objects=[o for o in scene.objects if o.name not in later])
        problem = placement_problem(model, sub, energy_only)
        x = problem.initial(draws, gen, proposals=options.proposals)
        if beam is not None:
            rows = torch.arange(len(x), device=x.device) % len(beam)
            x[:, [sub.index(m) for m in names[:k]]] = beam[rows]
        if ahead:
            _partner(model, sub, x, sub.index(names[k]), sub.index(names[k + 1]), gen)
        best = screen(problem.cost, x, keep)
        beam = best[:, [sub.index(m) for m in names[: k + 1]]]
    full = placement_problem(model, scene, energy_only)
    start = full.base_poses()[None].repeat(keep, 1, 1)
    assert beam is not None
    start[:, [scene.index(m) for m in names]] = beam
    return _in_pairs(model, full, start, draws, options.proposals, gen)


def _in_pairs(
    model: ScoreModel, problem: Problem, start: Tensor, draws: int, proposals: float, gen: torch.Generator
) -> Tensor:
    """:func:`in_turn`'s particles ``start`` improved by moves of one or two unknown objects in the whole
    scene: for each of ``problem``'s movable objects ``a`` in the scene's order, with ``b`` the next one
    (the last's: the first), ``draws`` rows copy the particles (cycled) and move ``a``: in the first
    half beside a known object near where the row has it (:func:`_near_draw`) with ``b`` put beside it
    where the data puts its kind (:func:`_partner`), in the next quarter beside a near object alone, in
    the last quarter anywhere (:meth:`~scenescore.problem.problem.Problem.initial`); the best ``len(start)`` of
    the particles and the rows are kept.

    The stages judge scenes with the later objects left out, which the data never shows (a table with an
    empty seat), and their choices can trap every particle: in zoo-cafe, with two chairs missing at one
    table and one at another, the stages put two chairs beside the table and off its seats, where moving
    either alone onto a seat scores worse and moving both scores best. A move beside a near object finds
    the seat next to where a chair stands; a draw beside any object of the room rarely does."""
    scene = problem.scene
    idx = [scene.index(n) for n in problem.movable]
    half, near = draws // 2, (3 * draws) // 4
    for i, a in enumerate(idx):
        b = idx[(i + 1) % len(idx)]
        x = start[torch.arange(draws, device=start.device) % len(start)].clone()
        _near_draw(model, problem, x[:near], a, gen)
        _partner(model, scene, x[: 2 * half], a, b, gen)
        x[near:, a] = problem.initial(draws - near, gen, proposals=proposals)[:, a]
        start = screen(problem.cost, torch.cat([start, x]), len(start))
    return start


def _near_draw(model: ScoreModel, problem: Problem, x: Tensor, a: int, gen: torch.Generator) -> None:
    """Put object ``a`` of each row of ``x`` at a pose the data has beside one of the
    :data:`NEAR_ANCHORS` known objects nearest to where the row has it (one drawn per row), kept inside
    the bounds (:meth:`~scenescore.problem.problem.Problem.inside`); in place. Rows stay as they are without
    relations for ``a``."""
    ref, scene = model.trust, problem.scene
    known = [j for j, o in enumerate(scene.objects) if o.pose is not None]
    if ref is None or not known:
        return
    idx, rel = ref.anchored(scene.objects[a].category, [scene.objects[j].category for j in known])
    if not len(idx):
        return
    dev = x.device
    counts = torch.as_tensor(np.bincount(idx, minlength=len(known)), device=dev)  # relations per anchor
    first = torch.cumsum(counts, 0) - counts  # each anchor's first row of ``rel`` (rows grouped by anchor)
    usable = torch.nonzero(counts).squeeze(1)
    at = torch.as_tensor(known, device=dev)[usable]  # the anchors' indices in the scene
    k = min(NEAR_ANCHORS, len(usable))
    nearest = torch.cdist(x[:, a, :2], x[0, at, :2]).topk(k, largest=False).indices  # (B, k)
    rows = torch.arange(len(x), device=dev)
    u = draw("rand", (len(x),), gen, dev, torch.float64)
    pick = usable[nearest[rows, (u * k).long().clamp(max=k - 1)]]  # (B,) an anchor per row
    v = draw("rand", (len(x),), gen, dev, torch.float64)
    r = first[pick] + (v * counts[pick]).long().clamp(max=counts[pick] - 1)
    rel_t = torch.as_tensor(rel, dtype=x.dtype, device=dev)[r]
    x[:, a] = problem.inside(compose_poses(x[rows, torch.as_tensor(known, device=dev)[pick]], rel_t))


def _partner(model: ScoreModel, scene: Scene, draws: Tensor, i: int, j: int, gen: torch.Generator) -> None:
    """Put object ``j`` of half of ``draws``' rows (the first half: its other rows keep their draws) at a
    pose relative to object ``i``'s draw that the data has between their categories, in place: an
    object is judged beside the next one to place, so that a slot whose neighbourhood the data only
    shows full (two chairs at a table for two) is found, where one object alone there scores worse than
    anywhere else."""
    ref = model.trust
    if ref is None:
        return
    _, rel = ref.anchored(scene.objects[j].category, [scene.objects[i].category])
    if not len(rel):
        return
    half = len(draws) // 2
    u = draw("rand", (half,), gen, draws.device, torch.float64)
    pick = (u * len(rel)).long().clamp(max=len(rel) - 1)
    r = torch.as_tensor(rel, dtype=draws.dtype, device=draws.device)[pick]
    draws[:half, j] = compose_poses(draws[:half, i], r)


def refining(options: LangevinOptions) -> LangevinOptions:
    """``options`` for particles that :func:`in_turn` found: its chain's gradient steps all noise-free at
    its final step size. Its exploring steps, large and noisy, carried several objects out of the
    narrow minimum of a full table (a chair a little off a slot for two scores worse than anywhere else)."""
    c = options.chain
    return replace(options, chain=replace(c, steps=0, final_descent=c.steps + c.final_descent))


def _starts(
    model: ScoreModel, scene: Scene, options: LangevinOptions, seed: int, energy_only: bool
) -> Tensor | None:
    """:func:`in_turn`'s particles where ``scene`` has several unknown objects and ``options`` screen
    candidates; None (the solver draws its own start) otherwise."""
    if len(scene.unknown) > 1 and options.candidates > options.particles:
        return in_turn(model, scene, options, seed, energy_only)
    return None


def place_many(
    model: ScoreModel,
    scenes: list[Scene],
    options: LangevinOptions | None = None,
    seed: int = 0,
    energy_only: bool = False,
    relations: bool = True,
) -> list[Scene]:
    """:func:`place` for several scenes at once: their problems solved together by
    :meth:`LangevinSolver.solve_many`, one batch per number of objects (the timings need it); without
    ``options``, :data:`PLACE` covering each batch's largest bounds (:func:`covering`). ``relations``:
    False leaves the relation a flagged placement doubts out of its flags (:func:`placement_problem`),
    where only whether it is flagged is read."""
    out = [s.copy() for s in scenes]
    groups: dict[int, list[int]] = {}
    for i, s in enumerate(scenes):
        if s.unknown:
            groups.setdefault(len(s), []).append(i)
    with torch_threads(1):  # tiny tensors; each batched chain chooses threads for its particles
        for idx in groups.values():
            problems = [placement_problem(model, scenes[i], energy_only, relations=relations) for i in idx]
            opts = options or covering(PLACE, model, [scenes[i] for i in idx])
            starts = [_starts(model, scenes[i], opts, seed + k, energy_only) for k, i in enumerate(idx)]
            init = None if any(x is None for x in starts) else cast(list[Tensor], starts)
            solver = LangevinSolver(opts if init is None else refining(opts))
            results = solver.solve_many(problems, seed=seed, init=init)
            for i, r in zip(idx, results):
                out[i] = _filled(scenes[i], r)
    return out


def _filled(scene: Scene, result: Result) -> Scene:
    """``scene`` with its unknown poses from ``result``, and their confidence in ``meta["placement"]``."""
    names = scene.unknown
    out = scene.with_poses(result.poses[[scene.index(n) for n in names]], names)
    out.meta = {
        **out.meta,
        "placement": {n: result.confidence[n].to_dict() for n in names if n in result.confidence},
    }
    return out


def place(
    model: ScoreModel,
    scene: Scene,
    options: LangevinOptions | None = None,
    seed: int = 0,
    energy_only: bool = False,
    extra: Cost | None = None,
) -> Scene:
    """Fill every ``null`` pose of ``scene`` (the others stay fixed); returns a new scene.

    This is ``ss.solve(placement_problem(model, scene), LangevinSolver(opts), seed=seed)`` with ``opts =
    options or covering(PLACE, model, [scene])``: placing and solving give the same answer for the same
    model, seed and options (for several unknown objects, with ``init=in_turn(model, scene, opts,
    seed)`` and :func:`refining` options: descent from particles found one object at a time and moved in
    pairs). By default the placed objects keep off the others (:func:`non_overlap`); ``energy_only``
    places by the learned energy alone; ``extra``: a cost added to the problem (:func:`placement_problem`). It runs on the model's device (``models.load(path,
    device="cuda")``).
    """
    if not scene.unknown:
        return scene.copy()
    with torch_threads(1):  # tiny tensors; the chain chooses threads for its particles
        opts = options or covering(PLACE, model, [scene])
        init = _starts(model, scene, opts, seed, energy_only)
        solver = LangevinSolver(opts if init is None else refining(opts))
        r = solve(placement_problem(model, scene, energy_only, extra), solver, init, seed=seed)
        return _filled(scene, r)


class Placer(Protocol):
    """A method for the missing-object experiments: fit on examples, then fill ``null`` poses."""

    name: str

    def fit(self, scenes: list[Scene], seed: int = 0) -> Placer: ...

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]: ...


@dataclass
class SceneScorePlacer:
    """SceneScore as a :class:`Placer`: train the energy, then Langevin placement."""

    name: str = "SceneScore"
    train_config: TrainConfig = field(default_factory=lambda: TrainConfig(**ONE_NETWORK))  # the paper's
    place_options: LangevinOptions | None = None  # None: PLACE, covering the bounds (covering)
    energy_only: bool = True  # the paper's protocol: the learned energy alone
    encoder: Encoder | None = None
    progress: bool = False
    model: ScoreModel | None = None
    device: str | None = None  # where the model trains and places (default the CPU)
    cache: str | os.PathLike | None = None  # a model cache folder (see scenescore.learn.cache)
    relations: bool = True  # a flagged placement's flags name the relation it doubts (placement_problem)

    def fit(self, scenes: list[Scene], seed: int = 0) -> SceneScorePlacer:
        self.model = fit(
            scenes,
            self.train_config,
            encoder=self.encoder,
            seed=seed,
            progress=self.progress,
            device=self.device,
            run=Run(cache=self.cache),
        )
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        if self.model is None:
            raise RuntimeError(f"{self.name}: call fit() before predict()")
        model, batch = self.model, 8  # scenes per batched solve
        out: list[Scene] = []
        bar = tqdm(total=len(scenes), desc="place", unit="scene", disable=not self.progress)
        # an experiment's placements after its trainings of one shape compiled: compiled chains
        compiled = compiled_placements(self.train_config)
        with bar, model.compiled_chains() if compiled else nullcontext():
            for k in range(0, len(scenes), batch):
                out += place_many(
                    model,
                    scenes[k : k + batch],
                    self.place_options,
                    seed + k,
                    self.energy_only,
                    self.relations,
                )
                bar.update(len(scenes[k : k + batch]))
        return out
